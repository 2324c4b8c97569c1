//! How parallel work runs: the one [`Executor`] of a computation — the
//! threads of this process (a rayon pool of a chosen size, or rayon's
//! global pool) and the ranks of a job (MPI, in the `etp` binary behind its
//! `mpi` feature; this crate knows only the [`Ranks`] trait and stays pure).
//! An executor is a value, passed in or held by a typed request: no library
//! keeps one in a global.
//!
//! A computation hands its `n` units to [`map`], which runs them on the
//! executor's pool: with one rank they are simulated on this process's
//! threads; with R ranks, rank r simulates the contiguous slice
//! [`slice()`]`(n, r, R)` (on its threads), encodes its results (bincode,
//! exact for `f64`) and the ranks all-gather the bytes, so every rank
//! decodes the same `n` results in unit order and continues identically.
//! Every unit draws its randomness from its own keyed stream and results are
//! kept in unit order, so they are the same bits for any number of ranks
//! and threads.
//!
//! The executor reaches the engines through the progress argument they
//! already take ([`Work`]): a plain `&|k| …` closure is a [`Work`] on
//! [`Executor::LOCAL`], and [`Executor::work`] pairs a closure with an
//! executor. A code path that does not go through [`map`] simply computes
//! everything on every rank — the same bits, only not shared out.

use rayon::prelude::*;
use serde::Serialize;
use serde::de::DeserializeOwned;
use std::ops::Range;
use std::sync::Arc;

/// Why the units of a computation could not be run or gathered.
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
    #[error("starting a pool of {threads} threads: {message}")]
    Pool { threads: usize, message: String },
}

/// A set of ranks that run the same computation and exchange its results
/// (the transport under an [`Executor`]: [`Local`], or MPI's world).
///
/// Contract: every rank calls [`Ranks::all_gather`] the same number of
/// times in the same order (they all run the same deterministic code).
pub trait Ranks: Sync + Send {
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

impl Ranks for Local {
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

/// Where a computation's units run: a thread pool and a set of ranks.
/// Cloning shares both (an [`Arc`] each).
#[derive(Clone, Default)]
pub struct Executor {
    /// The job's ranks; `None`: this process alone ([`Local`]).
    ranks: Option<Arc<dyn Ranks>>,
    /// The threads; `None`: rayon's global pool (`RAYON_NUM_THREADS`).
    pool: Option<Arc<rayon::ThreadPool>>,
}

impl std::fmt::Debug for Executor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Executor")
            .field("rank", &self.rank())
            .field("ranks", &self.ranks())
            .field("threads", &self.threads())
            .finish()
    }
}

impl Executor {
    /// This process alone on rayon's global pool (what a plain progress
    /// closure runs on).
    pub const LOCAL: Executor = Executor {
        ranks: None,
        pool: None,
    };

    /// This process alone on a pool of its own of `threads` threads (0:
    /// rayon's default, one per core).
    pub fn with_threads(threads: usize) -> Result<Self, ExecError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| ExecError::Pool {
                threads,
                message: e.to_string(),
            })?;
        Ok(Self {
            ranks: None,
            pool: Some(Arc::new(pool)),
        })
    }

    /// The same threads, shared out across `ranks`.
    pub fn on_ranks(self, ranks: Arc<dyn Ranks>) -> Self {
        Self {
            ranks: Some(ranks),
            ..self
        }
    }

    /// The same threads, this rank alone: its units all computed here, its
    /// files written here (`etp study` hands whole cases to ranks).
    pub fn alone(&self) -> Self {
        Self {
            ranks: None,
            pool: self.pool.clone(),
        }
    }

    /// The ranks' transport ([`Local`] when alone).
    fn transport(&self) -> &dyn Ranks {
        match &self.ranks {
            Some(r) => r.as_ref(),
            None => &Local,
        }
    }

    /// This process's index among the ranks.
    pub fn rank(&self) -> usize {
        self.transport().rank()
    }

    /// The number of ranks (≥ 1).
    pub fn ranks(&self) -> usize {
        self.transport().ranks()
    }

    /// Whether this process writes the outputs and draws progress: rank 0.
    pub fn is_root(&self) -> bool {
        self.rank() == 0
    }

    /// The threads units run on here.
    pub fn threads(&self) -> usize {
        match &self.pool {
            Some(p) => p.current_num_threads(),
            None => rayon::current_num_threads(),
        }
    }

    /// Every rank's bytes, in rank order (a collective operation: see
    /// [`Ranks`]).
    pub fn all_gather(&self, mine: Vec<u8>) -> Result<Vec<Vec<u8>>, ExecError> {
        self.transport().all_gather(mine)
    }

    /// Run `f` on this executor's threads (its rayon calls use them).
    pub fn install<T: Send>(&self, f: impl FnOnce() -> T + Send) -> T {
        match &self.pool {
            Some(p) => p.install(f),
            None => f(),
        }
    }

    /// A progress callback on this executor, for the engines'
    /// `progress: &dyn Work` arguments.
    pub fn work<F: Fn(u64) + Sync>(&self, progress: F) -> On<'_, F> {
        On {
            exec: self,
            progress,
        }
    }
}

/// What a long computation is handed: where its progress goes, and on
/// which executor its units run.
pub trait Work: Sync {
    /// `units` more units of work finished.
    fn progress(&self, units: u64);
    /// The executor of its units ([`Executor::LOCAL`] unless given).
    fn executor(&self) -> &Executor {
        &Executor::LOCAL
    }
}

impl<F: Fn(u64) + Sync> Work for F {
    fn progress(&self, units: u64) {
        self(units)
    }
}

/// A progress callback on a given executor ([`Executor::work`]).
pub struct On<'a, F> {
    exec: &'a Executor,
    progress: F,
}

impl<F: Fn(u64) + Sync> Work for On<'_, F> {
    fn progress(&self, units: u64) {
        (self.progress)(units)
    }
    fn executor(&self) -> &Executor {
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
        return Ok(exec.install(|| (0..n).into_par_iter().map(run).collect()));
    }
    let rank = exec.rank();
    let own = slice(n, rank, ranks);
    let mine: Vec<T> = exec.install(|| own.clone().into_par_iter().map(run).collect());
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

    impl Ranks for Fake {
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
    fn units_come_back_in_order_on_a_pool_of_any_size() {
        let f = |i: usize| (i as f64).sqrt().to_bits();
        let want: Vec<u64> = (0..100).map(f).collect();
        for threads in [1, 2, 3] {
            let exec = Executor::with_threads(threads).expect("a pool");
            assert_eq!(exec.threads(), threads);
            assert_eq!(exec.install(rayon::current_num_threads), threads);
            assert!(exec.is_root() && exec.alone().threads() == threads);
            let got = map(&exec.work(|_| {}), 100, f, |_| 1).expect("maps");
            assert_eq!(got, want, "{threads} threads");
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
                let exec = Executor::with_threads(2)
                    .expect("a pool")
                    .on_ranks(Arc::new(Fake {
                        rank,
                        ranks,
                        parts: Mutex::new(parts.clone()),
                    }));
                let count = std::sync::atomic::AtomicU64::new(0);
                let work = exec.work(|k| {
                    count.fetch_add(k, std::sync::atomic::Ordering::Relaxed);
                });
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
