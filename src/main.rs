//! exoleg binary: parse the command line, run, map errors to exit codes.

use clap::Parser;

fn main() {
    let cli = exoleg::cli::Cli::parse();
    match exoleg::cli::run(cli) {
        Ok(code) => std::process::exit(code),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(e.exit_code());
        }
    }
}
