//! The ranks of MPI's world (feature `mpi`): rsmpi over the system's MPI
//! library, the [`Ranks`] transport under `etp`'s executor. Each rank
//! simulates its slice of a computation's units; the encoded results are
//! all-gathered so every rank holds all of them.

use anyhow::{Result, bail};
use etp_synthesis::exec::{ExecError, Ranks};
use mpi::Threading;
use mpi::datatype::PartitionMut;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// MPI's environment: finalised when dropped.
pub struct Session {
    universe: mpi::environment::Universe,
}

impl Session {
    /// Finalise (normal end) or abort the job (an error on this rank).
    pub fn finish(self, code: u8, failed: bool) {
        if failed {
            eprintln!(
                "etp (rank {} of {}): aborting the MPI job",
                self.universe.world().rank(),
                self.universe.world().size()
            );
            self.universe.world().abort(i32::from(code.max(1)));
        }
        drop(self.universe);
    }
}

/// The ranks of `MPI_COMM_WORLD`.
#[derive(Debug, Clone, Copy)]
pub struct MpiWorld {
    pub rank: usize,
    size: usize,
}

/// Initialise MPI. The collectives may be called from a rayon worker (a
/// command run inside a thread pool), one at a time: `Serialized`.
pub fn start() -> Result<(Session, MpiWorld)> {
    let Some((universe, threading)) = mpi::initialize_with_threading(Threading::Serialized) else {
        bail!("MPI was already initialised");
    };
    if !matches!(threading, Threading::Serialized | Threading::Multiple) {
        tracing::debug!(
            "the MPI library offers {threading:?} threading; collectives stay on one thread at a time"
        );
    }
    let world = universe.world();
    let (rank, size) = (world.rank(), world.size());
    let world_ranks = MpiWorld {
        rank: usize::try_from(rank)?,
        size: usize::try_from(size)?,
    };
    Ok((Session { universe }, world_ranks))
}

/// Ranks other than 0 print nothing on stdout (their results are rank 0's).
#[allow(unsafe_code)]
pub fn silence_stdout() -> Result<()> {
    use std::os::fd::AsRawFd;
    let null = std::fs::OpenOptions::new().write(true).open("/dev/null")?;
    // SAFETY: dup2 on two valid descriptors, at start before any thread
    // writes to stdout; it only redirects fd 1.
    let r = unsafe { libc::dup2(null.as_raw_fd(), libc::STDOUT_FILENO) };
    if r < 0 {
        bail!("redirecting stdout: {}", std::io::Error::last_os_error());
    }
    Ok(())
}

/// Bytes one rank sends in one round: the displacements of a round stay
/// within MPI's `int` counts.
const ROUND_BYTES: usize = 1 << 30;

impl Ranks for MpiWorld {
    fn rank(&self) -> usize {
        self.rank
    }

    fn ranks(&self) -> usize {
        self.size
    }

    fn all_gather(&self, mine: Vec<u8>) -> Result<Vec<Vec<u8>>, ExecError> {
        let started = std::time::Instant::now();
        let world = SimpleCommunicator::world();
        let len = mine.len() as u64;
        let mut lens = vec![0u64; self.size];
        world.all_gather_into(&len, &mut lens[..]);
        let lens: Vec<usize> = lens
            .iter()
            .map(|&l| usize::try_from(l).map_err(|e| ExecError::Transport(e.to_string())))
            .collect::<Result<_, _>>()?;
        // Each round every rank sends at most `per` bytes of what is left.
        let per = (ROUND_BYTES / self.size).max(1);
        let rounds = lens.iter().map(|l| l.div_ceil(per)).max().unwrap_or(0);
        let mut parts: Vec<Vec<u8>> = lens.iter().map(|&l| Vec::with_capacity(l)).collect();
        for round in 0..rounds {
            let piece = |l: usize| (round * per).min(l)..((round + 1) * per).min(l);
            let counts: Vec<mpi::Count> = lens
                .iter()
                .map(|&l| mpi::Count::try_from(piece(l).len()))
                .collect::<Result<_, _>>()
                .map_err(|e| ExecError::Transport(e.to_string()))?;
            let mut displs = Vec::with_capacity(self.size);
            let mut total: mpi::Count = 0;
            for &c in &counts {
                displs.push(total);
                total += c;
            }
            let mut buf = vec![0u8; total as usize];
            {
                let mut partition = PartitionMut::new(&mut buf[..], &counts[..], &displs[..]);
                world.all_gather_varcount_into(&mine[piece(mine.len())], &mut partition);
            }
            for (k, part) in parts.iter_mut().enumerate() {
                let at = displs[k] as usize;
                part.extend_from_slice(&buf[at..at + counts[k] as usize]);
            }
        }
        // The MPI model of docs/performance.md ("MPI") is fitted to these
        // lines (`RUST_LOG=etp=debug`):
        // the seconds include the wait for the slowest rank.
        tracing::debug!(
            rank = self.rank,
            sent = len,
            received = lens.iter().sum::<usize>(),
            seconds = started.elapsed().as_secs_f64(),
            "all-gather"
        );
        Ok(parts)
    }
}
