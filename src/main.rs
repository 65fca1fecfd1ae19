//! The `layout-opt` command line. All work happens in the `layout_opt`
//! library; this binary parses flags into validated configurations, draws
//! progress, and prints errors as `Error: …` with a non-zero exit status.

mod cli;

fn main() {
    if let Err(error) = cli::run() {
        eprintln!("Error: {}", error_text(&error));
        std::process::exit(1);
    }
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
