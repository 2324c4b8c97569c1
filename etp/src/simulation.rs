//! The constant-threshold simulation `etp simulate` prints and `etp bench`
//! times: `etp_synthesis::constant`, its one home (shared with the Python
//! package; `#[inline]`, so still compiled in this crate).

pub use etp_synthesis::constant::{check_delta, simulate_constant};
