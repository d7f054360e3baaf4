//! Command-line interface (clap). Exit status: 0 success, 1 a negative answer
//! (unsafe, no plan), 2 bad input or usage, with the error on stderr.

mod bench_cmd;
#[cfg(feature = "service")]
mod client_cmd;
mod contour_cmd;
mod plan_cmd;
mod risk_cmd;
#[cfg(feature = "service")]
mod serve_cmd;
#[cfg(feature = "service")]
mod sim_cmd;
mod util;
mod verify_cmd;

use clap::{Parser, Subcommand};

/// riskplan: continuous-time risk-bounded trajectory planning with certified risk
/// contours (Jasour, Han, Williams, RSS 2021).
///
/// An obstacle is {x : P(x, ω, t) ≥ 0} with uncertain parameters ω. From the moments
/// of ω, riskplan builds the Cantelli risk contour of each obstacle (eqs. 10 and 12):
/// every point inside it has probability of collision with that obstacle at most Δ,
/// at that instant. Scenes are JSON files in scene format v1.
#[derive(Parser, Debug)]
#[command(name = "riskplan", version, about, long_about, max_term_width = 100)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    Risk(risk_cmd::RiskArgs),
    Contour(contour_cmd::ContourArgs),
    Verify(verify_cmd::VerifyArgs),
    Plan(plan_cmd::PlanArgs),
    Bench(bench_cmd::BenchArgs),
    #[cfg(feature = "service")]
    Serve(serve_cmd::ServeArgs),
    #[cfg(feature = "service")]
    Router(serve_cmd::RouterArgs),
    #[cfg(feature = "service")]
    Client(client_cmd::ClientArgs),
    #[cfg(feature = "service")]
    Sim(sim_cmd::SimArgs),
}

/// Runs the CLI and returns the exit status.
pub fn run() -> i32 {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() { 2 } else { 0 };
        }
    };
    let result = match cli.command {
        Command::Risk(a) => risk_cmd::run(a),
        Command::Contour(a) => contour_cmd::run(a),
        Command::Verify(a) => verify_cmd::run(a),
        Command::Plan(a) => plan_cmd::run(a),
        Command::Bench(a) => bench_cmd::run(a),
        #[cfg(feature = "service")]
        Command::Serve(a) => serve_cmd::run(a),
        #[cfg(feature = "service")]
        Command::Router(a) => serve_cmd::run_router(a),
        #[cfg(feature = "service")]
        Command::Client(a) => client_cmd::run(a),
        #[cfg(feature = "service")]
        Command::Sim(a) => sim_cmd::run(a),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            2
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Cli;
    use clap::CommandFactory;

    /// Every command's `--help` as a user reads it: clap prints doc comments as written, so
    /// the escapes that rustdoc needs (`E\[P\]`) would show; and every command explains itself.
    #[test]
    fn every_help_text_reads_without_rustdoc_escapes() {
        fn walk(cmd: &mut clap::Command, path: &str, seen: &mut usize) {
            let help = cmd.render_long_help().to_string();
            assert!(!help.contains("\\[") && !help.contains("\\]"), "`{path} --help` shows a rustdoc escape:\n{help}");
            assert!(cmd.get_about().is_some(), "`{path}` has no description");
            *seen += 1;
            for sub in cmd.get_subcommands_mut() {
                let name = format!("{path} {}", sub.get_name());
                walk(sub, &name, seen);
            }
        }
        let mut seen = 0;
        walk(&mut Cli::command(), "riskplan", &mut seen);
        assert!(seen >= 5, "only {seen} commands walked");
    }
}
