//! Where the units of a Monte Carlo computation run: the threads of this
//! process, or the ranks of a job (MPI, in the `etp` binary behind its `mpi`
//! feature; this crate knows only the [`Executor`] trait and stays pure).
//!
//! A computation hands its `n` units to [`map`]: with one rank they are
//! simulated on this process's threads, exactly as before; with R ranks,
//! rank r simulates the contiguous slice [`slice()`]`(n, r, R)` (on its
//! threads), encodes its results (bincode, exact for `f64`) and the executor
//! all-gathers the bytes, so every rank decodes the same `n` results in unit
//! order and continues identically. Every unit draws its randomness from its
//! own keyed stream, so the results are the same bits for any number of
//! ranks and threads.
//!
//! The executor reaches the engines through the progress argument they
//! already take ([`Work`]): a plain `&|k| …` closure is a [`Work`] on
//! [`Local`], and [`On`] pairs a closure with another executor. A code path
//! that does not go through [`map`] simply computes everything on every
//! rank — the same bits, only not shared out.

use rayon::prelude::*;
use serde::Serialize;
use serde::de::DeserializeOwned;
use std::ops::Range;

/// Why the units of a computation could not be gathered.
#[derive(Debug, thiserror::Error)]
pub enum ExecError {
    #[error("encoding the results of units {lo}..{hi}: {message}")]
    Encode {
        lo: usize,
        hi: usize,
        message: String,
    },
    #[error("decoding the results rank {rank} sent: {message}")]
    Decode { rank: usize, message: String },
    #[error("rank {rank} sent {got} results where its slice has {want}")]
    Count {
        rank: usize,
        got: usize,
        want: usize,
    },
    #[error("the executor gathered {got} parts from {want} ranks")]
    Parts { got: usize, want: usize },
    #[error("gathering the ranks' results: {0}")]
    Transport(String),
}

/// A set of ranks that run the same computation and exchange its results.
///
/// Contract: every rank calls [`Executor::all_gather`] the same number of
/// times in the same order (they all run the same deterministic code).
pub trait Executor: Sync {
    /// This process's index among the ranks.
    fn rank(&self) -> usize;
    /// The number of ranks (≥ 1).
    fn ranks(&self) -> usize;
    /// Every rank's bytes, in rank order (a collective operation).
    fn all_gather(&self, mine: Vec<u8>) -> Result<Vec<Vec<u8>>, ExecError>;
}

/// One rank: this process alone.
#[derive(Debug, Clone, Copy, Default)]
pub struct Local;

impl Executor for Local {
    fn rank(&self) -> usize {
        0
    }
    fn ranks(&self) -> usize {
        1
    }
    fn all_gather(&self, mine: Vec<u8>) -> Result<Vec<Vec<u8>>, ExecError> {
        Ok(vec![mine])
    }
}

/// What a long computation is handed: where its progress goes, and on
/// which executor its units run.
pub trait Work: Sync {
    /// `units` more units of work finished.
    fn progress(&self, units: u64);
    /// The executor of its units ([`Local`] unless given).
    fn executor(&self) -> &dyn Executor {
        &Local
    }
}

impl<F: Fn(u64) + Sync> Work for F {
    fn progress(&self, units: u64) {
        self(units)
    }
}

/// A progress callback on a given executor.
pub struct On<'a, F> {
    pub exec: &'a dyn Executor,
    pub progress: F,
}

impl<F: Fn(u64) + Sync> Work for On<'_, F> {
    fn progress(&self, units: u64) {
        (self.progress)(units)
    }
    fn executor(&self) -> &dyn Executor {
        self.exec
    }
}

/// The units of `n` that rank `rank` of `ranks` computes: contiguous, in
/// rank order, sizes differing by at most one.
pub fn slice(n: usize, rank: usize, ranks: usize) -> Range<usize> {
    let ranks = ranks.max(1);
    let (q, r) = (n / ranks, n % ranks);
    let start = |k: usize| k * q + k.min(r);
    start(rank.min(ranks))..start((rank + 1).min(ranks))
}

fn config() -> bincode::config::Configuration {
    bincode::config::standard()
}

/// `f(i)` for every unit `i < n`, in unit order, computed on the work's
/// executor (see the module documentation); `units(i)` progress units are
/// reported for unit `i` as it finishes here, or when it arrives from
/// another rank.
pub fn map<T, F, U>(work: &dyn Work, n: usize, f: F, units: U) -> Result<Vec<T>, ExecError>
where
    T: Serialize + DeserializeOwned + Send,
    F: Fn(usize) -> T + Sync,
    U: Fn(usize) -> u64 + Sync,
{
    let exec = work.executor();
    let ranks = exec.ranks();
    let run = |i: usize| {
        let t = f(i);
        work.progress(units(i));
        t
    };
    if ranks <= 1 {
        return Ok((0..n).into_par_iter().map(run).collect());
    }
    let rank = exec.rank();
    let own = slice(n, rank, ranks);
    let mine: Vec<T> = own.clone().into_par_iter().map(run).collect();
    let bytes = bincode::serde::encode_to_vec(&mine, config()).map_err(|e| ExecError::Encode {
        lo: own.start,
        hi: own.end,
        message: e.to_string(),
    })?;
    drop(mine);
    let parts = exec.all_gather(bytes)?;
    if parts.len() != ranks {
        return Err(ExecError::Parts {
            got: parts.len(),
            want: ranks,
        });
    }
    let mut out = Vec::with_capacity(n);
    for (r, part) in parts.iter().enumerate() {
        let range = slice(n, r, ranks);
        if r == rank {
            // Our own units: decoded like the others' (the same bits).
        } else {
            let done: u64 = range.clone().map(&units).sum();
            work.progress(done);
        }
        let (v, _): (Vec<T>, usize) =
            bincode::serde::decode_from_slice(part, config()).map_err(|e| ExecError::Decode {
                rank: r,
                message: e.to_string(),
            })?;
        if v.len() != range.len() {
            return Err(ExecError::Count {
                rank: r,
                got: v.len(),
                want: range.len(),
            });
        }
        out.extend(v);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    #[test]
    fn slices_cover_the_units_in_order() {
        for n in [0, 1, 5, 64, 1000] {
            for ranks in 1..=7 {
                let mut next = 0;
                for r in 0..ranks {
                    let s = slice(n, r, ranks);
                    assert_eq!(s.start, next);
                    assert!(s.len() <= n / ranks + 1 && s.len() >= n / ranks);
                    next = s.end;
                }
                assert_eq!(next, n);
            }
        }
    }

    /// R ranks simulated in one process: rank r's all_gather returns the
    /// parts every rank computed (run one after the other).
    struct Fake {
        rank: usize,
        ranks: usize,
        parts: Mutex<Vec<Vec<u8>>>,
    }

    impl Executor for Fake {
        fn rank(&self) -> usize {
            self.rank
        }
        fn ranks(&self) -> usize {
            self.ranks
        }
        fn all_gather(&self, mine: Vec<u8>) -> Result<Vec<Vec<u8>>, ExecError> {
            let mut parts = self
                .parts
                .lock()
                .map_err(|e| ExecError::Transport(e.to_string()))?;
            parts[self.rank] = mine;
            Ok(parts.clone())
        }
    }

    #[test]
    fn every_rank_gets_every_unit_in_order() {
        let n = 37;
        let f = |i: usize| (i as f64 * 0.1).sin();
        let want: Vec<f64> = (0..n).map(f).collect();
        for ranks in 1..=4 {
            // Each rank's own bytes, as the real ranks would send them.
            let parts: Vec<Vec<u8>> = (0..ranks)
                .map(|r| {
                    let mine: Vec<f64> = slice(n, r, ranks).map(f).collect();
                    bincode::serde::encode_to_vec(&mine, config()).expect("encodes")
                })
                .collect();
            for rank in 0..ranks {
                let exec = Fake {
                    rank,
                    ranks,
                    parts: Mutex::new(parts.clone()),
                };
                let count = std::sync::atomic::AtomicU64::new(0);
                let work = On {
                    exec: &exec,
                    progress: |k| {
                        count.fetch_add(k, std::sync::atomic::Ordering::Relaxed);
                    },
                };
                // The units this rank simulates itself: its slice, no more.
                let ran = Mutex::new(Vec::new());
                let g = |i: usize| {
                    ran.lock().expect("not poisoned").push(i);
                    f(i)
                };
                let got = map(&work, n, g, |_| 2).expect("maps");
                assert_eq!(got, want, "{ranks} ranks, rank {rank}");
                assert_eq!(count.into_inner(), 2 * n as u64);
                let mut ran = ran.into_inner().expect("not poisoned");
                ran.sort_unstable();
                let own: Vec<usize> = slice(n, rank, ranks).collect();
                assert_eq!(ran, own, "{ranks} ranks, rank {rank} simulated other units");
            }
        }
    }
}
