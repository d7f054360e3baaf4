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
    let cli = match Cli::try_parse_from(std::env::args_os().map(plain_negative_exponent)) {
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

/// The largest exponent [`plain_negative_exponent`] writes out (a longer number is left as
/// it is, and clap reports it as an unknown argument).
const MAX_PLAIN_EXPONENT: i64 = 400;

/// A negative number in exponent notation (`-1e-3`, `-2.5E+4`) written as a plain decimal
/// (`-0.001`, `-25000`), exactly, digit by digit; every other argument unchanged. clap takes
/// a value that starts with `-` for a flag unless it looks like a plain negative number, so
/// `--point -1e-3 0` would be refused as an unknown argument `-1` while `--point -0.001 0`
/// is read; no flag of riskplan looks like a number, so nothing else is rewritten.
fn plain_negative_exponent(arg: std::ffi::OsString) -> std::ffi::OsString {
    let Some(text) = arg.to_str() else { return arg };
    let Some(body) = text.strip_prefix('-') else { return arg };
    let Some((mantissa, exponent)) = body.split_once(['e', 'E']) else { return arg };
    let (int, frac) = mantissa.split_once('.').unwrap_or((mantissa, ""));
    let digits = |s: &str| s.bytes().all(|b| b.is_ascii_digit());
    let exp_digits = exponent.strip_prefix(['+', '-']).unwrap_or(exponent);
    if int.is_empty() || !digits(int) || !digits(frac) || exp_digits.is_empty() || !digits(exp_digits) {
        return arg;
    }
    let Ok(e) = exponent.parse::<i64>() else { return arg };
    if e.abs() > MAX_PLAIN_EXPONENT {
        return arg;
    }
    // the digits int·frac with the decimal point moved by e places
    let all = format!("{int}{frac}");
    let point = int.len() as i64 + e;
    let plain = if point <= 0 {
        format!("0.{}{all}", "0".repeat((-point) as usize))
    } else if point as usize >= all.len() {
        format!("{all}{}", "0".repeat(point as usize - all.len()))
    } else {
        format!("{}.{}", &all[..point as usize], &all[point as usize..])
    };
    format!("-{plain}").into()
}

#[cfg(test)]
mod tests {
    use super::Cli;

    #[test]
    fn negative_numbers_in_exponent_notation_become_plain_decimals() {
        let plain = |s: &str| super::plain_negative_exponent(s.into()).into_string().unwrap_or_default();
        assert_eq!(plain("-1e-3"), "-0.001");
        assert_eq!(plain("-1.5E-3"), "-0.0015");
        assert_eq!(plain("-2.5e+4"), "-25000");
        assert_eq!(plain("-12.34e1"), "-123.4");
        assert_eq!(plain("-7e0"), "-7");
        for kept in ["-1", "-0.5", "--time", "-h", "1e-3", "-e5", "-1e", "-1e-", "-1.2.3e4", "-1e999", "-x1e3", "-1e3x"]
        {
            assert_eq!(plain(kept), kept);
        }
        // and clap reads it as the number it is
        use clap::Parser;
        let cli = Cli::try_parse_from(
            ["riskplan", "risk", "--scene", "s.json", "--point", "-1e-3", "-2E1"]
                .map(|a| super::plain_negative_exponent(a.into())),
        );
        match cli.map(|c| c.command) {
            Ok(super::Command::Risk(_)) => {}
            Ok(_) => panic!("not the risk command"),
            Err(e) => panic!("{e}"),
        }
    }
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
