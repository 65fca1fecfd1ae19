//! The `layout-opt` command line. All work happens in the `layout_opt`
//! library; this binary parses flags into validated configurations, draws
//! progress, and prints errors as `Error: …` with a non-zero exit status.

mod cli;

fn main() {
    if let Err(error) = cli::run() {
        eprintln!("Error: {error:#}");
        std::process::exit(1);
    }
}
