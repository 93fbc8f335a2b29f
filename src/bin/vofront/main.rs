//! The `vofront` command line; see `vofront --help`.
//!
//! Exit codes: 0 success (for `two-view` and `relpose`: at least one estimate is `ok`);
//! 1 the job failed, with a one-line message saying why (no estimate at all); 2 bad command
//! line; 3 (`odometry`) tracking was lost for good, partial results written; 4 (`two-view`,
//! `relpose`) estimates were printed but none is `ok`; 130 / 143 (`odometry`) interrupted by
//! SIGINT / SIGTERM, every finished frame written.
/// `println!` that ends the process quietly (exit 141, as a SIGPIPE would) when standard
/// output has been closed, e.g. by `vofront ... | head`, instead of panicking.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if writeln!(std::io::stdout(), $($arg)*).is_err() {
            std::process::exit(141);
        }
    }};
}

/// `print!` with the same closed-pipe behaviour as [`outln!`].
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if write!(std::io::stdout(), $($arg)*).is_err() {
            std::process::exit(141);
        }
    }};
}

mod args;
mod compare_cmd;
mod demo;
mod eval_cmd;
mod odometry_cmd;
mod relpose;
mod two_view;

use std::process::ExitCode;

use clap::Parser;

use args::{Cli, Command};
use two_view::Status;

/// Exit status when estimates were printed but none is `ok`.
const EXIT_NONE_OK: u8 = 4;

/// Says so on standard error and exits with [`EXIT_NONE_OK`].
fn none_ok() -> ExitCode {
    eprintln!("vofront: no estimate is ok (see the verdicts and reasons printed)");
    ExitCode::from(EXIT_NONE_OK)
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => {
            out!("{e}");
            return ExitCode::SUCCESS;
        }
        Err(e) => {
            let rendered = e.render().to_string();
            let first = rendered.lines().next().unwrap_or("bad arguments");
            eprintln!("vofront: {}", first.trim_start_matches("error: "));
            return ExitCode::from(2);
        }
    };
    let result = match &cli.command {
        None => demo::run(),
        Some(Command::TwoView(a)) => match two_view::run(a) {
            Ok(Status::Ok) => Ok(()),
            Ok(Status::NoneOk) => return none_ok(),
            Ok(Status::NoEstimate) => Err("no estimator produced an estimate".to_string()),
            Err(e) => Err(e),
        },
        Some(Command::Relpose(a)) => match relpose::run(a) {
            Ok(true) => Ok(()),
            Ok(false) => return none_ok(),
            Err(e) => Err(e),
        },
        Some(Command::Odometry(a)) => match odometry_cmd::run(a) {
            Ok(0) => Ok(()),
            Ok(code) => return ExitCode::from(code),
            Err(e) => Err(e),
        },
        Some(Command::Eval(a)) => eval_cmd::run(a),
        Some(Command::Compare(a)) => match compare_cmd::run(a) {
            Ok(0) => Ok(()),
            Ok(code) => return ExitCode::from(code),
            Err(e) => Err(e),
        },
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("vofront: {message}");
            ExitCode::FAILURE
        }
    }
}
