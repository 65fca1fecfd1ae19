//! The `layout-opt` command line. All work happens in the `layout_opt`
//! library; this binary parses flags into validated configurations, draws
//! progress, and prints errors as `Error: …` with a non-zero exit status.

mod cli;

use layout_opt::kernel::{Interrupted, StopRequest};

/// Exit status of a run stopped by Ctrl-C (128 + SIGINT, as shells report).
const EXIT_INTERRUPTED: i32 = 130;

fn main() {
    catch_ctrl_c();
    if let Err(error) = cli::run() {
        if let Some(stopped) = error.chain().find_map(|c| c.downcast_ref::<Interrupted>()) {
            eprintln!("{stopped}");
            std::process::exit(EXIT_INTERRUPTED);
        }
        eprintln!("Error: {}", error_text(&error));
        std::process::exit(1);
    }
}

/// Turns the first Ctrl-C into the process's stop request, which a
/// command's observer polls and its run answers with [`Interrupted`]. A
/// second Ctrl-C, or one while nothing polls the request (a command with no
/// observer, whose outputs are written atomically at its end), ends the
/// process at once, with status 130.
fn catch_ctrl_c() {
    // Without a handler (none could be installed) Ctrl-C ends the process
    // as the system does by default, which is still status 130.
    let _ = ctrlc::set_handler(|| {
        if StopRequest::request() || !StopRequest::watched() {
            std::process::exit(EXIT_INTERRUPTED);
        }
    });
}

/// The error and its causes joined by ": ", each said once: a cause whose
/// text the message already contains (library errors often quote their
/// source, as in "cannot read layout file x.json: No such file or
/// directory") is left out rather than repeated.
fn error_text(error: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in error.chain() {
        let part = cause.to_string();
        if part.is_empty() || text.contains(&part) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&part);
    }
    text
}

#[cfg(test)]
mod tests {
    use super::error_text;
    use anyhow::Context;

    #[test]
    fn a_quoted_cause_is_said_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file");
        let error: anyhow::Error = std::fs::read("/nonexistent/x.json")
            .map_err(|_| io)
            .context("cannot read x.json: No such file")
            .unwrap_err();
        assert_eq!(error_text(&error), "cannot read x.json: No such file");
        let chained = anyhow::anyhow!("inner").context("outer");
        assert_eq!(error_text(&chained), "outer: inner");
    }
}
