//! Where etpareto writes, and what it trusts on disk. Every path under a
//! folder other users can reach may be a planted link; every output may be
//! interrupted half-way. Two modules hold the rules every process and
//! command follows:
//!
//! * [`folders`] — the user's private folders (iceoryx2 roots, run folders,
//!   sensor-host domains), created 0700 and checked without following
//!   links; the checks of a folder an output goes into
//!   ([`folders::output_folder`], [`folders::check_ancestors`]).
//! * [`write`](mod@write) — the overwrite rule (`--force` or refuse) and the safe
//!   writer: an output is written to a sibling created exclusively and
//!   renamed into place only once complete ([`write::write_via_temp`],
//!   [`write::write_new`]). Its errors are [`write::WriteError`].
//!
//! Both are std only: no crate of the runtime, the recording or the maths
//! is needed to write a file safely.

pub mod folders;
pub mod write;
