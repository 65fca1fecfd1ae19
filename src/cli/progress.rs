//! Progress bars: drawn on stderr only when it is a terminal and `--quiet`
//! was not given. Ctrl-C reaches the observer as the process's stop request
//! ([`StopRequest`]), which `main` sets.

use indicatif::{ProgressBar, ProgressStyle};
use layout_opt::kernel::StopRequest;
use layout_opt::observer::Observer;
use std::io::IsTerminal;

/// A progress bar of `total` steps, hidden when not on a terminal or quiet.
pub fn bar(total: u64, message: &str, quiet: bool) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() || !std::io::stdout().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(total);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} ({eta})")
            .expect("the template is valid")
            .progress_chars("=> "),
    );
    bar.set_message(message.to_string());
    bar
}

/// What one step of a pipeline phase is, for its bar.
fn unit(phase: &str) -> &'static str {
    use layout_opt::search::{PHASE_COMPARE, PHASE_SEARCH, PHASE_VALIDATE};
    match phase {
        PHASE_SEARCH => "iterations",
        PHASE_COMPARE | PHASE_VALIDATE | layout_opt::validate::image_check::PHASE => "scenarios",
        layout_opt::render::workflow::PHASE_CHECK => "poses",
        layout_opt::render::workflow::PHASE_RENDER | layout_opt::track::workflow::PHASE_TRACK => {
            "frames"
        }
        _ => "steps",
    }
}

/// A named phase's bar: the phase, the bar, steps done of the phase's whole
/// budget in its unit, time spent and the estimate of time left.
fn phase_bar(phase: &str, total: u64, quiet: bool) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() || !std::io::stdout().is_terminal() {
        return ProgressBar::hidden();
    }
    ProgressBar::new(total)
        .with_style(
            ProgressStyle::with_template(
                "{prefix:>10} [{bar:40}] {pos}/{len} {msg} ({elapsed} spent, about {eta} left)",
            )
            .expect("the template is valid")
            .progress_chars("=> "),
        )
        .with_prefix(phase.to_string())
        .with_message(unit(phase))
}

/// The terminal's observer: one progress bar per phase, log lines on
/// stderr, Ctrl-C as interruption.
pub struct Bars {
    quiet: bool,
    phase: String,
    bar: Option<ProgressBar>,
}

impl Bars {
    /// No bar yet; `quiet` hides them all. From now on Ctrl-C asks the run
    /// to stop rather than ending the process.
    pub fn new(quiet: bool) -> Self {
        StopRequest::watch();
        Self {
            quiet,
            phase: String::new(),
            bar: None,
        }
    }

    /// Clears the last bar.
    pub fn finish(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }
}

impl Observer for Bars {
    fn progress(&mut self, phase: &str, done: u64, total: u64) {
        if self.phase != phase || self.bar.is_none() {
            self.finish();
            self.phase = phase.to_string();
            self.bar = Some(phase_bar(phase, total, self.quiet));
        }
        if let Some(bar) = &self.bar {
            bar.set_position(done);
        }
    }

    fn interrupted(&self) -> bool {
        StopRequest::requested()
    }

    fn log(&mut self, line: &str) {
        match &self.bar {
            Some(bar) => bar.suspend(|| eprintln!("{line}")),
            None => eprintln!("{line}"),
        }
    }
}
