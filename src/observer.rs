//! What a long-running pipeline tells its caller while it works, and how the
//! caller asks it to stop. Library code never prints: progress, log lines and
//! interruption all go through an [`Observer`], which the command line turns
//! into progress bars and Ctrl-C handling and a library user may ignore
//! ([`Silent`]).

use std::sync::atomic::{AtomicBool, Ordering};

/// The caller's side of a pipeline run. Every method has a do-nothing
/// default; the pipeline calls them from the thread that called it.
pub trait Observer {
    /// `phase` has done `done` of `total` steps (a new `phase` name starts a
    /// new phase).
    fn progress(&mut self, phase: &str, done: u64, total: u64) {
        let _ = (phase, done, total);
    }

    /// Whether the caller wants the run to stop early; polled while the
    /// interruptible phases run.
    fn interrupted(&self) -> bool {
        false
    }

    /// A line worth showing the user (what the run decided, not progress).
    fn log(&mut self, line: &str) {
        let _ = line;
    }
}

/// An observer that ignores everything and never interrupts.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Observer for Silent {}

/// Collects log lines and never interrupts: for tests and callers that want
/// the messages without a terminal.
#[derive(Debug, Clone, Default)]
pub struct Collect {
    /// Every line logged, in order.
    pub lines: Vec<String>,
}

impl Observer for Collect {
    fn log(&mut self, line: &str) {
        self.lines.push(line.to_string());
    }
}

/// Runs `work` on a scoped thread while this thread relays its progress:
/// every few milliseconds `observer` hears `phase` at `done()` of `total`
/// and, when `stop` is given, an [`Observer::interrupted`] caller sets it.
pub(crate) fn watch<T: Send>(
    observer: &mut impl Observer,
    phase: &str,
    total: u64,
    done: impl Fn() -> u64,
    stop: Option<&AtomicBool>,
    work: impl FnOnce() -> T + Send,
) -> T {
    observer.progress(phase, 0, total);
    relay(
        observer,
        |o| o.progress(phase, done().min(total), total),
        stop,
        work,
    )
}

/// Runs `work` on a scoped thread while this thread calls `report` on
/// `observer` every few milliseconds (and once at the end) and, when `stop`
/// is given, sets it once the observer is [`Observer::interrupted`], also
/// before the work starts (so work asked to stop at once never begins).
pub(crate) fn relay<O: Observer, T: Send>(
    observer: &mut O,
    report: impl Fn(&mut O),
    stop: Option<&AtomicBool>,
    work: impl FnOnce() -> T + Send,
) -> T {
    const POLL: std::time::Duration = std::time::Duration::from_millis(20);
    if let Some(stop) = stop {
        if observer.interrupted() {
            stop.store(true, Ordering::SeqCst);
        }
    }
    std::thread::scope(|scope| {
        let handle = scope.spawn(work);
        while !handle.is_finished() {
            std::thread::sleep(POLL);
            if let Some(stop) = stop {
                if observer.interrupted() {
                    stop.store(true, Ordering::SeqCst);
                }
            }
            report(observer);
        }
        let result = handle
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        report(observer);
        result
    })
}
