"""Tables from ``etpareto._native`` as pandas DataFrames.

The compiled module hands a table over column by column: ``(name, dtype,
data, mask)`` with ``dtype`` one of ``u8``/``i8``/``f8``/``bool`` (``data``
little-endian bytes, read by :func:`numpy.frombuffer` without a per-value
copy) or ``str`` (``data`` a list of ``str``/``None``); ``mask`` marks rows
without a value (bytes, or ``None`` when every row has one).
"""

from __future__ import annotations

from typing import Any, Sequence, Tuple

import numpy as np
import pandas as pd

Column = Tuple[str, str, Any, Any]

_DTYPES = {"u8": "<u8", "i8": "<i8", "f8": "<f8", "bool": "?"}
_NULLABLE = {"u8": "UInt64", "i8": "Int64", "bool": "boolean"}


def _series(col: Column) -> Tuple[str, Any]:
    name, dtype, data, mask = col
    if dtype == "str":
        return name, pd.Series(data, dtype="string")
    values = np.frombuffer(data, dtype=_DTYPES[dtype]).copy()
    if mask is None:
        return name, values
    missing = np.frombuffer(mask, dtype="?")
    series = pd.Series(values, dtype=_NULLABLE.get(dtype, values.dtype))
    series[missing] = pd.NA
    return name, series


def frame(columns: Sequence[Column]) -> pd.DataFrame:
    """A DataFrame of the columns, in their order."""
    return pd.DataFrame(dict(_series(c) for c in columns))


def arrays(columns: Sequence[Column]) -> dict:
    """The columns as NumPy arrays (``str`` columns as object arrays)."""
    out = {}
    for name, series in (_series(c) for c in columns):
        out[name] = series.to_numpy() if isinstance(series, pd.Series) else series
    return out
