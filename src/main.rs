//! exoleg binary: parse the command line, run, map errors to exit codes.

use clap::Parser;

fn main() {
    exoleg::cli::remove_outputs_on_signals();
    let cli = match exoleg::cli::Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if e.use_stderr() => {
            // One line, like every other error: clap's first line, then where to look.
            let text = e.render().to_string();
            let first = text.lines().next().unwrap_or("error: bad arguments").trim_end();
            eprintln!("{first} (see --help)");
            exoleg::cli::exit(exoleg::error::EXIT_BAD_INPUT);
        }
        Err(e) => e.exit(),
    };
    let result = exoleg::cli::run(cli);
    // Built with the feature `stage-timing`: where the loops' time went (src/profile.rs).
    if let Some(table) = exoleg::profile::report() {
        eprintln!("stage costs (feature stage-timing):\n{table}");
    }
    match result {
        Ok(code) => exoleg::cli::exit(code),
        Err(e) => {
            eprintln!("error: {e}");
            exoleg::cli::exit(e.exit_code());
        }
    }
}
