//! `cable-servo`: command-line front end. All work happens in the library.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use cable_servo::run::{self, OutputOptions, RunError, RunReport, SweepOptions};
use cable_servo::scenario::{Scenario, DEFAULT_SCENARIO};
use cable_servo::sweep::Shard;

/// Exit codes, listed in the README.
mod exit {
    /// Bad command line (clap's own code).
    pub const USAGE: u8 = 2;
    /// Bad input: scenario, `--set`, bench log, table.
    pub const INPUT: u8 = 3;
    /// The physics stopped the run (slack, gross slip, unstable loop...): results kept and
    /// marked incomplete.
    pub const PHYSICAL: u8 = 4;
    /// Results could not be written (existing directory without --force, disk).
    pub const OUTPUT: u8 = 5;
}

#[derive(Parser)]
#[command(
    name = "cable-servo",
    version,
    about = "Preloaded cable-drive physics, closed-loop pointing simulation and bench-log diagnosis",
    long_about = "Simulate a preloaded cable (capstan) drive with history-dependent backlash, close a \
discrete PID loop around it, sweep design parameters, and diagnose measured bench logs.\n\n\
Scenario files are TOML; every command accepts repeated --set KEY=VALUE overrides, \
validated like the file (e.g. --set drive.preload_n=70 --set drive.routing=open).\n\
Built-in scenarios (usable by name from any directory): eots_tracking, paper_bench, paper_fig11."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run one scenario; writes timeseries.csv, summary.json and plots.
    Run {
        /// Scenario file or built-in name (default: the EOTS tracking study).
        scenario: Option<String>,
        /// Results directory (default: results/<scenario name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Override a scenario value, e.g. drive.preload_n=70 (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Replace an existing results directory.
        #[arg(long)]
        force: bool,
    },
    /// Run the sweep a scenario declares; writes sweep.csv (one row per case), summary.json
    /// and plots.
    Sweep {
        /// Scenario file or built-in name with a [sweep] section.
        scenario: String,
        /// Results directory (default: results/<scenario name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Override a scenario value (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Worker threads (default: all cores).
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Run only shard K of N (cluster array jobs); join shards with `merge`.
        #[arg(long, value_name = "K/N")]
        shard: Option<String>,
        /// Replace an existing results directory.
        #[arg(long)]
        force: bool,
    },
    /// Join the sweep.csv files of shard runs into the file a single run writes.
    Merge {
        /// Output file (e.g. results/paper_fig11/sweep.csv).
        #[arg(long)]
        out: PathBuf,
        /// Shard results: sweep.csv files or directories holding one.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
        /// Replace an existing output file.
        #[arg(long)]
        force: bool,
    },
    /// Print a built-in scenario (to copy and edit).
    Show {
        /// Built-in scenario name.
        name: String,
    },
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { exit::USAGE } else { 0 });
        }
    };
    match cli.command {
        Command::Run {
            scenario,
            out,
            set,
            force,
        } => {
            let name = scenario.as_deref().unwrap_or(DEFAULT_SCENARIO);
            let scenario = match load(name, &set) {
                Ok(s) => s,
                Err(code) => return code,
            };
            let dir = out.unwrap_or_else(|| PathBuf::from("results").join(scenario.name()));
            report(run::run_scenario(&scenario, &OutputOptions { dir, force }))
        }
        Command::Sweep {
            scenario,
            out,
            set,
            threads,
            shard,
            force,
        } => {
            let shard = match shard.as_deref().map(Shard::parse).transpose() {
                Ok(s) => s.unwrap_or(Shard::ALL),
                Err(msg) => {
                    eprintln!("error: {msg}");
                    return ExitCode::from(exit::USAGE);
                }
            };
            let scenario = match load(&scenario, &set) {
                Ok(s) => s,
                Err(code) => return code,
            };
            let dir = out.unwrap_or_else(|| PathBuf::from("results").join(scenario.name()));
            let total = scenario.sweep.as_ref().map_or(0, |s| {
                cable_servo::sweep::expand(s)
                    .iter()
                    .filter(|c| shard.owns(c.index))
                    .count()
            });
            let bar = indicatif::ProgressBar::new(total as u64);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{elapsed_precise} [{bar:40}] {pos}/{len} cases ({per_sec}, eta {eta})",
                )
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            let tick = || bar.inc(1);
            let result = run::run_sweep(
                &scenario,
                &SweepOptions {
                    output: OutputOptions { dir, force },
                    threads,
                    shard,
                },
                &tick,
            );
            bar.finish_and_clear();
            report(result)
        }
        Command::Merge { out, shards, force } => {
            match cable_servo::sweep::merge::merge_files(&shards, &out, force) {
                Ok(rows) => {
                    println!("{rows} cases merged into {}", out.display());
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::from(e.exit_code())
                }
            }
        }
        Command::Show { name } => match cable_servo::scenario::builtin(&name) {
            Some(text) => {
                print!("{text}");
                ExitCode::SUCCESS
            }
            None => {
                let names: Vec<&str> = cable_servo::scenario::BUILTIN.iter().map(|b| b.0).collect();
                eprintln!(
                    "error: no built-in scenario {name:?}; built-in: {}",
                    names.join(", ")
                );
                ExitCode::from(exit::INPUT)
            }
        },
    }
}

/// Load a scenario and fill its tables; prints the error and returns the exit code.
fn load(name: &str, set: &[String]) -> Result<Scenario, ExitCode> {
    let mut scenario = Scenario::load(name, set).map_err(|e| {
        eprintln!("error: {e}");
        ExitCode::from(exit::INPUT)
    })?;
    let base = std::path::Path::new(name)
        .parent()
        .map(std::path::Path::to_path_buf)
        .unwrap_or_default();
    cable_servo::io::tables::load_tables(&mut scenario, &base).map_err(|e| {
        eprintln!("error: {e}");
        ExitCode::from(exit::INPUT)
    })?;
    Ok(scenario)
}

fn report(result: Result<RunReport, RunError>) -> ExitCode {
    match result {
        Ok(r) => {
            for w in &r.warnings {
                eprintln!("warning: {w}");
            }
            print!("{}", r.table);
            println!("results: {}", r.dir.display());
            match &r.failure {
                None => ExitCode::SUCCESS,
                Some(f) => {
                    eprintln!("error: run incomplete (results kept, marked INCOMPLETE): {f}");
                    ExitCode::from(exit::PHYSICAL)
                }
            }
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(match e {
                RunError::Scenario(_)
                | RunError::Table(_)
                | RunError::Sweep(_)
                | RunError::ClosedLoop(_)
                | RunError::Unsupported(_) => exit::INPUT,
                RunError::Output(_) | RunError::Report(_) | RunError::ClosedLoopReport(_) => {
                    exit::OUTPUT
                }
            })
        }
    }
}
