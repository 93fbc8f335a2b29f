//! The `vofront` command line; see `vofront --help`.
//!
//! Exit codes: 0 success (for `two-view`: at least one estimator produced an estimate);
//! 1 the job failed, with a one-line message saying why; 2 bad command line; 3 (`odometry`)
//! tracking was lost for good, partial results written; 130 / 143 (`odometry`) interrupted by
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
mod demo;
mod eval_cmd;
mod odometry_cmd;
mod relpose;
mod two_view;

use std::process::ExitCode;

use clap::Parser;

use args::{Cli, Command};

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
        Some(Command::TwoView(a)) => two_view::run(a).and_then(|any| {
            if any {
                Ok(())
            } else {
                Err("no estimator produced an estimate".to_string())
            }
        }),
        Some(Command::Relpose(a)) => relpose::run(a),
        Some(Command::Odometry(a)) => match odometry_cmd::run(a) {
            Ok(0) => Ok(()),
            Ok(code) => return ExitCode::from(code),
            Err(e) => Err(e),
        },
        Some(Command::Eval(a)) => eval_cmd::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("vofront: {message}");
            ExitCode::FAILURE
        }
    }
}
