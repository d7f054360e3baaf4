//! The `riskplan` command-line tool: see `riskplan --help` (the commands live in the
//! library's `cli` module, feature `cli`).

fn main() {
    std::process::exit(riskplan::cli::run());
}
