//! How a run is asked to stop, and how it says it stopped.
//!
//! A process has one stop request: the binary's Ctrl-C handler sets it, and
//! the terminal's observer reads it ([`crate::observer::Observer::interrupted`]),
//! so that every workflow polls the same flag through the observer it is
//! given. A workflow that stops early returns its own error's interrupted
//! case; the command line turns that into [`Interrupted`], which the binary
//! alone maps to exit status 130.

use crate::observer::Observer;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// How often [`abandon_on_stop`] asks its observer.
const POLL: Duration = Duration::from_millis(20);

/// Set once the process has been asked to stop.
static REQUESTED: AtomicBool = AtomicBool::new(false);
/// Set once something polls the request (an observer that relays it).
static WATCHED: AtomicBool = AtomicBool::new(false);

/// The process's stop request.
#[derive(Debug, Clone, Copy, Default)]
pub struct StopRequest;

impl StopRequest {
    /// Asks every run of this process to stop; says whether it had been
    /// asked already (a second request).
    pub fn request() -> bool {
        REQUESTED.swap(true, Ordering::SeqCst)
    }

    /// Whether the process has been asked to stop.
    pub fn requested() -> bool {
        REQUESTED.load(Ordering::SeqCst)
    }

    /// Says that this process polls the request: until then, a handler
    /// should end the process at once rather than ask a run that never
    /// looks.
    pub fn watch() {
        WATCHED.store(true, Ordering::SeqCst);
    }

    /// Whether something polls the request ([`StopRequest::watch`]).
    pub fn watched() -> bool {
        WATCHED.load(Ordering::SeqCst)
    }

    /// The request as a flag, for the engines that poll an `AtomicBool`.
    pub fn flag() -> &'static AtomicBool {
        &REQUESTED
    }
}

/// A run that stopped because it was asked to. Its text says what was kept
/// (nothing, or a best-so-far file). Exit status 130 belongs to this error.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{kept}")]
pub struct Interrupted {
    /// What the run left on disk, in words.
    pub kept: String,
}

impl Interrupted {
    /// A run that stopped and wrote nothing.
    pub fn nothing_written() -> Self {
        Self::keeping("interrupted; no output written")
    }

    /// A run that stopped and kept what `kept` says.
    pub fn keeping(kept: impl Into<String>) -> Self {
        Self { kept: kept.into() }
    }
}

/// Runs `work` on a thread of its own while this thread asks `observer`
/// every 20 ms whether to stop; returns the work's result, or
/// [`Interrupted`] as soon as the observer asks, without waiting for the
/// work, which runs on unobserved and whose result is dropped. Only for
/// work that writes nothing (an analysis before its files): abandoning it
/// loses nothing, and the stop is answered within one poll however long
/// the work's own steps are. A panic of the work is this thread's panic.
pub fn abandon_on_stop<O: Observer + ?Sized, T: Send + 'static>(
    observer: &mut O,
    work: impl FnOnce() -> T + Send + 'static,
) -> Result<T, Interrupted> {
    if observer.interrupted() {
        return Err(Interrupted::nothing_written());
    }
    let handle = std::thread::spawn(work);
    while !handle.is_finished() {
        std::thread::sleep(POLL);
        if observer.interrupted() {
            return Err(Interrupted::nothing_written());
        }
    }
    handle
        .join()
        .map_err(|panic| std::panic::resume_unwind(panic))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Instant;

    /// Asks to stop once `after` has passed.
    struct StopAfter {
        from: Instant,
        after: Duration,
    }

    impl Observer for StopAfter {
        fn interrupted(&self) -> bool {
            self.from.elapsed() >= self.after
        }
    }

    #[test]
    fn abandoned_work_is_answered_within_a_poll_and_finished_work_returns() {
        let mut observer = StopAfter {
            from: Instant::now(),
            after: Duration::from_millis(50),
        };
        let result = abandon_on_stop(&mut observer, || {
            std::thread::sleep(Duration::from_secs(5));
            1
        });
        assert_eq!(result, Err(Interrupted::nothing_written()));
        assert!(observer.from.elapsed() < Duration::from_secs(1));
        let mut patient = StopAfter {
            from: Instant::now(),
            after: Duration::from_secs(3600),
        };
        assert_eq!(abandon_on_stop(&mut patient, || 2), Ok(2));
    }

    #[test]
    fn an_interruption_says_what_it_kept() {
        assert_eq!(
            Interrupted::nothing_written().to_string(),
            "interrupted; no output written"
        );
        assert_eq!(
            Interrupted::keeping("best so far in a.partial.json").to_string(),
            "best so far in a.partial.json"
        );
    }
}
