//! Progress of long work on stderr: an indicatif bar on a terminal; when
//! stderr is not a terminal (a pipe, a log file, CI) one plain line every
//! [`LINE_EVERY`] (`synthesize: 1200/6000 (20 %) after 10 s, ~40 s left`),
//! so piped output is never silent for long. `quiet` (`--json`) hides both:
//! machine output stays clean. `ETP_PROGRESS_SECONDS` sets the interval of
//! the plain lines (tests use a short one).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::time::{Duration, Instant};

/// Interval of the plain progress lines.
pub const LINE_EVERY: Duration = Duration::from_secs(5);

/// A bar of `len` units with a message.
pub fn bar(len: u64, message: &str, quiet: bool) -> ProgressBar {
    let pb = ProgressBar::new(len);
    let terminal = std::io::stderr().is_terminal();
    if quiet || !terminal {
        pb.set_draw_target(ProgressDrawTarget::hidden());
    }
    pb.set_style(
        ProgressStyle::with_template("{msg:>12} [{bar:40}] {pos}/{len} ({eta} left)")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb.set_message(message.to_string());
    if !quiet && !terminal {
        let every = std::env::var("ETP_PROGRESS_SECONDS")
            .ok()
            .and_then(|v| v.parse::<f64>().ok())
            .and_then(|s| Duration::try_from_secs_f64(s).ok())
            .filter(|d| !d.is_zero())
            .unwrap_or(LINE_EVERY);
        lines(&pb, message.to_string(), every);
    }
    pb
}

/// One line `what: pos/len (p %) after t s, ~r s left`.
pub fn line(what: &str, pos: u64, len: u64, elapsed: Duration) -> String {
    let secs = elapsed.as_secs_f64();
    if len == 0 {
        return format!("{what}: {pos} after {secs:.0} s");
    }
    let frac = pos as f64 / len as f64;
    let left = if frac > 0.0 {
        format!(", ~{:.0} s left", secs * (1.0 - frac) / frac)
    } else {
        String::new()
    };
    format!(
        "{what}: {pos}/{len} ({:.0} %) after {secs:.0} s{left}",
        100.0 * frac
    )
}

/// Print a [`line`] of `pb` every `every` until it is finished or dropped
/// (a detached thread holding only a weak reference).
fn lines(pb: &ProgressBar, what: String, every: Duration) {
    let weak = pb.downgrade();
    let started = Instant::now();
    std::thread::spawn(move || {
        let tick = Duration::from_millis(200).min(every);
        let mut next = every;
        loop {
            std::thread::sleep(tick);
            let Some(pb) = weak.upgrade() else { return };
            if pb.is_finished() {
                return;
            }
            if started.elapsed() >= next {
                next += every;
                eprintln!(
                    "{}",
                    line(
                        &what,
                        pb.position(),
                        pb.length().unwrap_or(0),
                        started.elapsed()
                    )
                );
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn progress_lines_say_how_far_and_how_long() {
        assert_eq!(
            line("synthesize", 1200, 6000, Duration::from_secs(10)),
            "synthesize: 1200/6000 (20 %) after 10 s, ~40 s left"
        );
        assert_eq!(
            line("run", 0, 100, Duration::from_secs(5)),
            "run: 0/100 (0 %) after 5 s"
        );
    }
}
