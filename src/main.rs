//! The `riskplan` command-line tool: see `riskplan --help`.

mod cli;

fn main() {
    std::process::exit(cli::run());
}
