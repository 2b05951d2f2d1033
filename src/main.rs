//! `cable-servo`: command-line front end. All work happens in the library.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use cable_servo::run::{self, OutputOptions, RunError, RunReport, SweepOptions};
use cable_servo::scenario::{Scenario, DEFAULT_SCENARIO};
use cable_servo::study::answers;
use cable_servo::sweep::{vary, Shard};

/// Print a line to stdout, long numbers compacted; a closed pipe (`| head`) is not an
/// error worth a panic.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let text = cable_servo::long_numbers_compacted(&format!($($arg)*));
        let _ = writeln!(std::io::stdout(), "{text}");
    }};
}

/// Print to stdout without a newline, ignoring a closed pipe.
macro_rules! say_raw {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stdout(), $($arg)*);
    }};
}

/// Print a line to stderr, long numbers compacted, ignoring a closed pipe.
macro_rules! tell {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let text = cable_servo::long_numbers_compacted(&format!($($arg)*));
        let _ = writeln!(std::io::stderr(), "{text}");
    }};
}

/// A run or sweep estimated to compute longer than this (s) says so before it starts.
const LONG_RUN_S: f64 = 10.0;

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
Built-in scenarios (usable by name from any directory): eots_tracking (the default), eots_scan, \
eots_mismatch, eots_runout, step_stare, eots_tolerance, paper_bench, paper_tension, memory_vs_memoryless, \
paper_fig11, gimbal_ident, davinci_tool4, davinci_tool4_loop, gimbal_stabilized; `cable-servo show NAME` \
prints one.\n\n\
Exit codes: 0 success, 2 usage error, 3 input error, 4 a requirement not met or a run the physics \
stopped (results kept, marked incomplete), 5 output error (existing results without --force), 130/143 interrupted by \
SIGINT/SIGTERM."
)]
struct Cli {
    /// Without a command: `run` of the default study (eots_tracking) into a fresh
    /// directory under `results/`.
    #[command(subcommand)]
    command: Option<Command>,
}

/// A bisection on closed-loop runs for the largest value that meets the pointing target.
#[derive(clap::Args)]
struct TargetSearch {
    /// Closed-loop scenario file or built-in name.
    scenario: Option<String>,
    /// Compensation mode judged: none, memoryless or memory.
    #[arg(long, default_value = "memory")]
    mode: String,
    /// Lower end of the search (N m or Hz).
    #[arg(long)]
    min: Option<f64>,
    /// Upper end of the search (N m or Hz).
    #[arg(long)]
    max: Option<f64>,
    /// Bisection tolerance (N m or Hz).
    #[arg(long)]
    tol: Option<f64>,
    /// Override a scenario value (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
}

#[derive(Subcommand)]
enum Design {
    /// Largest brake load (N m) at which the closed loop still meets the pointing target
    /// with the given compensation (breakaway torque scaled with it). Defaults: scenario
    /// eots_tracking, range 0.05 to 3 N m, tolerance 0.02 N m.
    LargestLoad(TargetSearch),
    /// Fastest scan (reference frequency, Hz, amplitude unchanged) at which the closed loop
    /// still meets the pointing target with the given compensation. Defaults: scenario
    /// eots_scan, range 0.05 to 5 Hz, tolerance 0.02 Hz.
    FastestScan(TargetSearch),
    /// Tune the gains of the scenario's plain PID: a log grid screened on the exact
    /// linear loop with the margins held over the operating range (free span and the
    /// tangent at the operating load), then a pattern search judged by the verdict on the
    /// nonlinear plant, with and without load feedforward. Writes tuned.toml (runnable),
    /// candidates.csv, summary.json and figures. Exit 0 when the pick meets every
    /// requirement, 4 when it misses the target or nothing is signable.
    Tune {
        /// Closed-loop scenario file or built-in name (default: eots_tracking).
        scenario: Option<String>,
        /// Control rate to tune at, Hz (default: the scenario's).
        #[arg(long, value_name = "HZ")]
        rate: Option<f64>,
        /// Compensation mode judged: none, memoryless or memory (default: the scenario's
        /// judged mode, closed_loop.requirements.mode or its last listed mode; a --mode
        /// other than a declared one is refused).
        #[arg(long)]
        mode: Option<String>,
        /// Load feedforward tried: off, on or both (the pick is the better).
        #[arg(long, default_value = "both", value_name = "off|on|both")]
        feedforward: String,
        /// Filters searched besides the gains, comma-separated: derivative, notch,
        /// lead-lag, or none (each variant screened on the linear loop, the best two
        /// and the scenario's own searched in full; a few minutes).
        #[arg(long, default_value = "none", value_name = "LIST")]
        filters: String,
        /// A reduced search (coarse grid, a few runs): a quick look, not an answer.
        #[arg(long)]
        quick: bool,
        /// Results directory (default: results/<scenario>-tune, or the next free).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace an existing results directory written by this program.
        #[arg(long)]
        force: bool,
        /// Override a scenario value (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
    },
    /// Least control rate at which a tuned, signable PID meets the pointing target:
    /// bisection over the rate with a tune at each probe. The passing end of the bracket
    /// carries a verified design; the failing end is where the search found none.
    LeastRate {
        /// Closed-loop scenario file or built-in name (default: eots_tracking).
        scenario: Option<String>,
        /// Compensation mode judged: none, memoryless or memory (default: the scenario's
        /// judged mode, closed_loop.requirements.mode or its last listed mode; a --mode
        /// other than a declared one is refused).
        #[arg(long)]
        mode: Option<String>,
        /// Load feedforward tried at each rate: off, on or both.
        #[arg(long, default_value = "off", value_name = "off|on|both")]
        feedforward: String,
        /// Lower end of the search, Hz (the scenario must accept it: well above the
        /// plant's fastest mode).
        #[arg(long, default_value_t = 8000.0)]
        min_hz: f64,
        /// Upper end of the search, Hz.
        #[arg(long, default_value_t = 20000.0)]
        max_hz: f64,
        /// Bisection tolerance, Hz.
        #[arg(long, default_value_t = 250.0)]
        tol_hz: f64,
        /// A reduced search at each rate (coarse grid, a few runs).
        #[arg(long)]
        quick: bool,
        /// Results directory (default: results/<scenario>-least-rate, or the next free).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace an existing results directory written by this program.
        #[arg(long)]
        force: bool,
        /// Override a scenario value (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
    },
    /// Least preload (N) at which the +M, -M, +M backlash protocol at the given load runs
    /// with no slack span and no gross slip (drive otherwise as in the scenario).
    LeastPreload {
        /// Scenario file or built-in name giving the drive (default: paper_fig11).
        scenario: Option<String>,
        /// Transmitted torque M, N m (default: the scenario's backlash.load_nm, else its
        /// peak load).
        #[arg(long = "load-nm", value_name = "M")]
        load_nm: Option<f64>,
        /// Override a scenario value (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Lower end of the search, N.
        #[arg(long, default_value_t = 0.01)]
        min_n: f64,
        /// Upper end of the search, N.
        #[arg(long, default_value_t = 1e5)]
        max_n: f64,
        /// Bisection tolerance, N.
        #[arg(long, default_value_t = 0.01)]
        tol_n: f64,
    },
}

#[derive(Subcommand)]
enum Command {
    /// Run one scenario; writes timeseries.csv, summary.json and plots.
    Run {
        /// Scenario file or built-in name (default: the EOTS tracking study).
        scenario: Option<String>,
        /// Results directory (default: results/<scenario name>, or the first free
        /// results/<scenario name>-2, -3, ... when it exists; with --force it is replaced).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Override a scenario value, e.g. drive.preload_n=70 (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Replace an existing results directory written by this program (a file or a
        /// directory of other content is refused).
        #[arg(long)]
        force: bool,
    },
    /// Run the sweep a scenario declares; writes sweep.csv (one row per case), summary.json
    /// and plots.
    Sweep {
        /// Scenario file or built-in name with a [sweep] section.
        scenario: String,
        /// Results directory (default: results/<scenario name>-sweep, or the first free
        /// -sweep-2, -sweep-3, ...).
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
        /// Vary a scenario key (repeatable; replaces the file's parameter of that key).
        /// SPEC: a,b,c | start:stop:step | lin(start,stop,n) | log(start,stop,n) |
        /// uniform(min,max) | normal(mean,std) | tnormal(mean,std,min,max) |
        /// uniform_rel(tol) | normal_rel(std[,tol]), e.g. drive.preload_n=10:100:10.
        #[arg(long = "vary", value_name = "KEY=SPEC")]
        vary: Vec<String>,
        /// How cases are formed: grid, list, random or latin_hypercube (default: the
        /// file's; random when --samples, --seed or a distribution is given).
        #[arg(long, value_name = "MODE")]
        mode: Option<String>,
        /// Cases drawn in random and latin_hypercube modes.
        #[arg(long, value_name = "N")]
        samples: Option<usize>,
        /// Master seed of random and latin_hypercube draws.
        #[arg(long, value_name = "S")]
        seed: Option<u64>,
        /// Also write every case's time series to cases/case-NNNNNN/ (quasi-static).
        #[arg(long)]
        case_timeseries: bool,
        /// Replace an existing results directory written by this program (a file or a
        /// directory of other content is refused).
        #[arg(long)]
        force: bool,
    },
    /// Compare controller designs side by side: several closed-loop scenarios, or one
    /// scenario with named sets of overrides. Writes compare.csv, summary.json, each
    /// design's files under designs/ and overlay plots; exit code 4 when a design fails
    /// its requirements (its verdict: pointing, margins, stability, as `run` judges them).
    Compare {
        /// Scenario files or built-in names: each one a design (with --design: the one
        /// base scenario the designs change).
        scenarios: Vec<String>,
        /// A design as NAME:KEY=VALUE;KEY=VALUE... on the base scenario (repeatable),
        /// e.g. --design 'notch:closed_loop.controller.command_filters=[{kind="notch",center_hz=40.0,depth_db=20.0,width_hz=20.0}]'.
        #[arg(long = "design", value_name = "NAME:SETS")]
        designs: Vec<String>,
        /// Compensation mode compared (default: the last one each scenario lists).
        #[arg(long)]
        mode: Option<String>,
        /// Override a value in every design (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Results directory (default: results/compare, or the first free compare-2, ...).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace an existing results directory written by this program.
        #[arg(long)]
        force: bool,
    },
    /// Design answers computed directly (no sweep table).
    Design {
        #[command(subcommand)]
        question: Design,
    },
    /// Diagnose bench logs: what the simulation gets wrong, its physical cause, and the
    /// gain of the extended model on data the fit did not see.
    Diagnose {
        /// Scenario giving the drive (and optional [identify] settings).
        #[arg(long)]
        scenario: String,
        /// Bench log (CSV, see data-format); repeat for several logs in one calibration.
        #[arg(long = "data", value_name = "LOG.csv", required = true)]
        data: Vec<PathBuf>,
        /// Hold out whole logs by index (0-based, in --data order) instead of time blocks.
        #[arg(long = "holdout", value_name = "INDEX")]
        holdout: Vec<usize>,
        /// Cut this many seconds from the start of every log (start-up transient); default:
        /// a load step at the start is detected and cut with its settling; 0 keeps all.
        #[arg(long = "cut-start", value_name = "SECONDS")]
        cut_start: Option<f64>,
        /// Leave each log out in turn: calibrate the shared model on the others, score it on
        /// the one left out beside a play operator fitted to it (needs two or more logs).
        #[arg(long = "leave-one-out")]
        leave_one_out: bool,
        /// Fit and score the stretches flagged as not the drive (a jerk, a stuck reading,
        /// a departure from the input's motion) instead of excluding them; they are still
        /// reported, marked "kept".
        #[arg(long = "keep-segments")]
        keep_segments: bool,
        /// Effect of the extension scored by --leave-one-out (repeatable; default: the
        /// scenario's [identify] candidates, every effect when that list is empty, as
        /// for a single diagnosis). Only with --leave-one-out; a single diagnosis
        /// searches the scenario's [identify] candidates, e.g. --set
        /// 'identify.candidates=["load_compliance"]'.
        #[arg(long = "extension", value_name = "EFFECT")]
        extension: Vec<String>,
        /// Results directory (default: results/<scenario name>-diagnosis, or with
        /// --leave-one-out results/<scenario name>-leave-one-out; the next free -2, -3, ...
        /// when it exists, or replaced with --force).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Also write the JSON report here.
        #[arg(long, value_name = "FILE")]
        json: Option<PathBuf>,
        /// Write the calibrated, extended model as a scenario file.
        #[arg(long = "save-model", value_name = "FILE")]
        save_model: Option<PathBuf>,
        /// Override a scenario value (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Replace an existing results directory, --json and --save-model files written by
        /// this program (anything else at those paths is refused).
        #[arg(long)]
        force: bool,
    },
    /// Make a synthetic bench log from a truth model with hidden effects, noise and
    /// quantisation (motion from the scenario's quasi_static section).
    Synth {
        /// Scenario giving drive, load and motion.
        #[arg(long)]
        scenario: String,
        /// Hidden effect NAME=VALUE (units: see docs/diagnose.md), repeatable.
        #[arg(long = "effect", value_name = "NAME=VALUE")]
        effect: Vec<String>,
        /// Random seed (noise and runout phases).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Output log file.
        #[arg(long)]
        out: PathBuf,
        /// Override a scenario value (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Replace an existing file.
        #[arg(long)]
        force: bool,
    },
    /// Join the sweep.csv files of shard runs into the file a single run writes. Every
    /// cell is checked against its column (finite numbers, blank figures only for cases
    /// without them, status and regime words, true/false); a bad cell is refused with its
    /// file, line, column and what is allowed, and nothing is written (exit 3).
    Merge {
        /// Output file (e.g. results/paper_fig11/sweep.csv).
        #[arg(long)]
        out: PathBuf,
        /// Shard results: sweep.csv files or directories holding one.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
        /// Replace an existing merged table (only a sweep table; anything else is refused).
        #[arg(long)]
        force: bool,
        /// Merge even with shards missing or cut short; the result is marked partial
        /// (terminal and `<out>.merge.json`).
        #[arg(long)]
        partial: bool,
    },
    /// Margins of a closed-loop design on its exact linear reference (cable as its linear
    /// spring, zero-order hold, PID and computation delay as implemented), then the
    /// design's verdict. Writes margins.json (every crossing, Ms, closed-loop poles, step
    /// figures), linear_model.json (the plant's matrices and the discrete controller for
    /// python-control or MATLAB: docs/linear-model.md), summary.json and Bode, Nyquist,
    /// Nichols, z-plane and step figures.
    Margins {
        /// Scenario file or built-in name (default: eots_tracking).
        scenario: Option<String>,
        /// Override a scenario key (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Explore another load: crossings, files and figures at the tangent stiffness of
        /// first loading to this transmitted torque, N m, in place of the declared
        /// operating load's. The verdict and exit code stay the design's as declared
        /// (closed_loop.requirements.operating_load_nm sets the load it is judged at).
        #[arg(long = "load-nm", value_name = "M")]
        load_nm: Option<f64>,
        /// Results directory (default: results/<scenario name>-margins, or the next free).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace an existing results directory written by this program.
        #[arg(long)]
        force: bool,
    },
    /// Frequency response of the simulated (nonlinear) loop by sinusoidal injection at one
    /// loop point and one or more amplitudes; margins, sensitivity peak and bandwidth of
    /// each amplitude beside the exact linear reference; CSV, JSON, Bode and Nyquist plots.
    /// Settings default to the scenario's [closed_loop.freqresp] section; flags override.
    /// Exit 4 when the design misses a requirement or a measurement run stopped (slip,
    /// slack, instability: results kept, marked incomplete); a frequency the measurement
    /// could not resolve at its amplitude is listed with its reason, not failing.
    Freqresp {
        /// Closed-loop scenario file or built-in name (default: eots_tracking).
        scenario: Option<String>,
        /// Loop point: plant_input (L), output_disturbance (S), input_disturbance (PS),
        /// reference (T_r), base_motion (line of sight over base angle), plant (the plant's
        /// describing function with the loop open, and the limit cycles it predicts).
        #[arg(long)]
        point: Option<String>,
        /// Injection amplitudes, comma-separated: A (or V) at the plant input and the
        /// plant, output mrad elsewhere.
        #[arg(long, value_delimiter = ',', num_args = 1..)]
        amplitudes: Vec<f64>,
        /// Frequencies, Hz, comma-separated (instead of the log range).
        #[arg(long, value_delimiter = ',', num_args = 1..)]
        frequencies: Vec<f64>,
        /// Lowest frequency of the log range, Hz.
        #[arg(long)]
        f_min: Option<f64>,
        /// Highest frequency of the log range, Hz (default 0.4 x Nyquist).
        #[arg(long)]
        f_max: Option<f64>,
        /// Frequencies in the log range.
        #[arg(long)]
        points: Option<usize>,
        /// Operating point: rest (reference held at zero) or slewing (a constant-rate
        /// ramp under the injection, so a brake or Coulomb friction slides). Default:
        /// slewing where such friction would hold the axis, rest otherwise.
        #[arg(long, value_name = "rest|slewing")]
        operating_point: Option<String>,
        /// Slew rate of the slewing operating point, output rad/s (default: twice the
        /// injection's largest output velocity on the exact linear reference).
        #[arg(long, value_name = "RAD_S")]
        slew_rate: Option<f64>,
        /// Worker threads (default: all cores).
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Results directory (default: results/<scenario name>-freqresp, or the next free).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Override a scenario value (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Replace an existing results directory written by this program.
        #[arg(long)]
        force: bool,
    },
    /// Export the plant of a closed-loop scenario as an FMI 2.0 Co-Simulation FMU (motor,
    /// cable drive, drum, loads, encoders; the host closes the loop). Needs the shared
    /// library built next to this binary (`cargo build --release` builds both).
    ExportFmu {
        /// Closed-loop scenario file or built-in name (its values become the FMU's defaults).
        scenario: String,
        /// FMU file to write.
        #[arg(long, default_value = "drive.fmu")]
        out: PathBuf,
        /// Override a scenario value (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Shared library to pack (default: libcable_servo.so next to this binary).
        #[arg(long, value_name = "PATH")]
        library: Option<PathBuf>,
        /// Replace an existing file.
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
    cable_servo::io::signals::install();
    let command = cli.command.unwrap_or(Command::Run {
        scenario: None,
        out: None,
        set: Vec::new(),
        force: false,
    });
    match command {
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
            let dir = out.unwrap_or_else(|| {
                run::default_results_dir(&PathBuf::from("results").join(scenario.name()), force)
            });
            if let Some(w) = run::work_estimate(&scenario).filter(|w| w.wall_s > LONG_RUN_S) {
                tell!(
                    "this run computes for about {} ({} mode(s) x {} control periods, side by side on the cores) and holds about {:.0} MB",
                    cable_servo::duration_words(w.wall_s),
                    w.modes,
                    w.periods,
                    w.memory_mb
                );
            }
            let budget = run::progress::Bar::new("error budget", "runs");
            let result =
                run::run_scenario_with_progress(&scenario, &OutputOptions { dir, force }, &budget);
            budget.finish();
            report(result)
        }
        Command::Compare {
            scenarios,
            designs,
            mode,
            set,
            out,
            force,
        } => compare(scenarios, designs, mode, set, out, force),
        Command::Sweep {
            scenario,
            out,
            set,
            threads,
            shard,
            vary,
            mode,
            samples,
            seed,
            case_timeseries,
            force,
        } => {
            let shard = match shard.as_deref().map(Shard::parse).transpose() {
                Ok(s) => s.unwrap_or(Shard::ALL),
                Err(msg) => {
                    tell!("error: {msg}");
                    return ExitCode::from(exit::USAGE);
                }
            };
            let overrides = match mode.as_deref().map(vary::parse_mode).transpose() {
                Ok(mode) => vary::SweepOverrides {
                    vary,
                    mode,
                    samples,
                    seed,
                },
                Err(msg) => {
                    tell!("error: {msg}");
                    return ExitCode::from(exit::USAGE);
                }
            };
            let mut scenario = match load(&scenario, &set) {
                Ok(s) => s,
                Err(code) => return code,
            };
            if !overrides.is_empty() {
                match overrides.apply(scenario.sweep.take()) {
                    Ok(spec) => scenario.sweep = Some(spec),
                    Err(msg) => {
                        tell!("error: {msg}");
                        return ExitCode::from(exit::INPUT);
                    }
                }
            }
            // Its own default beside a run's, so `run X` then `sweep X` never collide.
            let dir = out.unwrap_or_else(|| {
                run::default_results_dir(
                    &PathBuf::from("results").join(format!("{}-sweep", scenario.name())),
                    force,
                )
            });
            let threads = sane_threads(threads);
            let total = scenario.sweep.as_ref().map_or(0, |s| {
                (0..s.case_count()).filter(|&i| shard.owns(i)).count()
            });
            if let Some((wall_s, _)) =
                run::sweep_wall_estimate(&scenario, total, threads).filter(|(s, _)| *s > LONG_RUN_S)
            {
                tell!(
                    "this sweep computes for about {} ({total} cases)",
                    cable_servo::duration_words(wall_s)
                );
            }
            let bar = indicatif::ProgressBar::new(total as u64);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{elapsed_precise} [{bar:40}] {pos}/{len} cases ({per_sec}, eta {eta})",
                )
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            let tick = || bar.inc(1);
            // A signal now stops the sweep between cases; the rows finished are kept.
            let _graceful = cable_servo::io::signals::Graceful::begin();
            let result = run::run_sweep(
                &scenario,
                &SweepOptions {
                    output: OutputOptions { dir, force },
                    threads,
                    shard,
                    case_timeseries,
                },
                &tick,
            );
            bar.finish_and_clear();
            report(result)
        }
        Command::Design {
            question: Design::LargestLoad(search),
        } => closed_loop_answer(
            &search,
            "eots_tracking",
            cable_servo::design::Question::LargestLoad,
            (0.05, 3.0, 0.02),
        ),
        Command::Design {
            question: Design::FastestScan(search),
        } => closed_loop_answer(
            &search,
            "eots_scan",
            cable_servo::design::Question::FastestScan,
            (0.05, 5.0, 0.02),
        ),
        Command::Design {
            question:
                Design::Tune {
                    scenario,
                    rate,
                    mode,
                    feedforward,
                    filters,
                    quick,
                    out,
                    force,
                    set,
                },
        } => design_tune(
            scenario,
            rate,
            (mode.as_deref(), &feedforward, &filters),
            quick,
            out,
            force,
            set,
        ),
        Command::Design {
            question:
                Design::LeastRate {
                    scenario,
                    mode,
                    feedforward,
                    min_hz,
                    max_hz,
                    tol_hz,
                    quick,
                    out,
                    force,
                    set,
                },
        } => design_least_rate(
            scenario,
            mode.as_deref(),
            &feedforward,
            (min_hz, max_hz, tol_hz),
            quick,
            out,
            force,
            set,
        ),
        Command::Design {
            question:
                Design::LeastPreload {
                    scenario,
                    load_nm,
                    set,
                    min_n,
                    max_n,
                    tol_n,
                },
        } => {
            let scenario = match load(scenario.as_deref().unwrap_or("paper_fig11"), &set) {
                Ok(s) => s,
                Err(code) => return code,
            };
            let load_nm = load_nm.unwrap_or_else(|| {
                scenario
                    .backlash
                    .as_ref()
                    .map_or(scenario.load.peak_torque_nm(), |b| b.load_nm)
            });
            if !(load_nm.is_finite() && load_nm > 0.0) {
                tell!(
                    "error: --load-nm {}: give a torque > 0 N m",
                    cable_servo::readable(load_nm)
                );
                return ExitCode::from(exit::USAGE);
            }
            if !(min_n > 0.0 && max_n > min_n && tol_n > 0.0) {
                tell!("error: need 0 < --min-n < --max-n and --tol-n > 0");
                return ExitCode::from(exit::USAGE);
            }
            let model = scenario
                .backlash
                .as_ref()
                .map(|b| b.model)
                .unwrap_or_default();
            let r = answers::least_preload_at_load(
                &scenario.drive,
                load_nm,
                model,
                (min_n, max_n),
                tol_n,
            );
            say!(
                "least preload at M = {} N m ({} model): {}",
                cable_servo::readable(load_nm),
                cable_servo::study::quasi_static::model_name(model),
                r.preload_n.map_or(
                    format!("none up to {} N", cable_servo::number(r.range_n.1)),
                    |p| format!(
                        "{} N (+{} N, {} probes)",
                        cable_servo::significant(p, 6),
                        cable_servo::compact(r.tolerance_n),
                        r.probes
                    )
                )
            );
            if let Some(note) = &r.note {
                say!("  note: {note}");
            }
            say!(
                "  for comparison M/(2*drum_radius_m) = {} N (slack limit if span tensions moved equally and oppositely)",
                cable_servo::fixed(r.slack_bound_n, 3)
            );
            say!("  definition: {}", r.definition);
            if r.preload_n.is_some() {
                ExitCode::SUCCESS
            } else {
                ExitCode::from(exit::PHYSICAL)
            }
        }
        Command::Diagnose {
            scenario,
            data,
            holdout,
            cut_start,
            leave_one_out,
            keep_segments,
            extension,
            out,
            json,
            save_model,
            set,
            force,
        } => {
            // Silently ignored, it would leave the user believing the effect was searched.
            if !leave_one_out && !extension.is_empty() {
                tell!(
                    "error: --extension names the extension that --leave-one-out scores, and is \
                     not used without it. To search {} in a single diagnosis, set the scenario's \
                     [identify] candidates (the list replaces the default one), e.g. --set \
                     'identify.candidates=[{}]'",
                    extension.join(", "),
                    extension
                        .iter()
                        .map(|e| format!("\"{e}\""))
                        .collect::<Vec<_>>()
                        .join(", ")
                );
                return ExitCode::from(exit::USAGE);
            }
            // --leave-one-out holds every log out in turn; a fixed hold-out would be ignored.
            if leave_one_out && !holdout.is_empty() {
                tell!(
                    "error: --holdout holds fixed logs out of a single diagnosis and is not used with --leave-one-out, which holds out every log in turn; drop --holdout, or drop --leave-one-out to score the extension on log(s) {}",
                    holdout
                        .iter()
                        .map(|k| k.to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                );
                return ExitCode::from(exit::USAGE);
            }
            if let Some(k) = holdout.iter().find(|k| **k >= data.len()) {
                tell!(
                    "error: --holdout {k}: there {} {} --data log(s), indexed 0 to {} in --data order; name a log that is given, and keep at least one for calibration",
                    if data.len() == 1 { "is" } else { "are" },
                    data.len(),
                    data.len().saturating_sub(1)
                );
                return ExitCode::from(exit::USAGE);
            }
            let mut held: Vec<usize> = holdout.clone();
            held.sort_unstable();
            held.dedup();
            if !held.is_empty() && held.len() >= data.len() {
                tell!(
                    "error: --holdout holds out every --data log; keep at least one for calibration"
                );
                return ExitCode::from(exit::USAGE);
            }
            let scenario = match load(&scenario, &set) {
                Ok(s) => s,
                Err(code) => return code,
            };
            let dir = out.clone().unwrap_or_else(|| {
                run::default_results_dir(
                    &PathBuf::from("results").join(format!("{}-diagnosis", scenario.name())),
                    force,
                )
            });
            let start = match cut_start {
                None => cable_servo::identify::startup::StartMode::Detect,
                Some(s) if s.is_finite() && s >= 0.0 => {
                    cable_servo::identify::startup::StartMode::Fixed(s)
                }
                Some(s) => {
                    tell!("error: --cut-start {s}: must be a time in seconds, 0 or more");
                    return ExitCode::from(exit::USAGE);
                }
            };
            let options = cable_servo::identify::DiagnoseOptions {
                holdout_logs: holdout,
                start,
                keep_segments,
                ..Default::default()
            };
            if leave_one_out {
                let mut effects = Vec::new();
                for e in &extension {
                    match e.parse::<cable_servo::identify::EffectName>() {
                        Ok(x) => effects.push(x),
                        Err(m) => {
                            tell!("error: --extension: {m}");
                            return ExitCode::from(exit::USAGE);
                        }
                    }
                }
                let dir = out.unwrap_or_else(|| {
                    run::default_results_dir(
                        &PathBuf::from("results")
                            .join(format!("{}-leave-one-out", scenario.name())),
                        force,
                    )
                });
                let folds = cable_servo::run::progress::Bar::new("leave-one-out", "logs");
                let result = cable_servo::run::run_leave_one_out_with_progress(
                    &scenario,
                    &data,
                    &effects,
                    start,
                    keep_segments,
                    &OutputOptions { dir, force },
                    json.as_deref(),
                    save_model.as_deref(),
                    &folds,
                );
                folds.finish();
                return report(result);
            }
            let judged = cable_servo::run::progress::Bar::new("diagnosis", "candidates");
            let result = cable_servo::run::run_diagnosis_with_progress(
                &scenario,
                &data,
                &options,
                &OutputOptions { dir, force },
                json.as_deref(),
                save_model.as_deref(),
                &judged,
            );
            judged.finish();
            report(result)
        }
        Command::Synth {
            scenario,
            effect,
            seed,
            out,
            set,
            force,
        } => {
            let scenario = match load(&scenario, &set) {
                Ok(s) => s,
                Err(code) => return code,
            };
            use cable_servo::io::staging::{check_file_target, FileKind};
            if let Err(e) = check_file_target(&out, force, FileKind::BenchLog) {
                tell!("error: {e}");
                return ExitCode::from(exit::OUTPUT);
            }
            let effects: Result<Vec<_>, _> = effect
                .iter()
                .map(|e| cable_servo::identify::parse_effect_arg(e))
                .collect();
            let result = effects.and_then(|effects| {
                cable_servo::identify::synthesize(
                    &scenario,
                    &effects,
                    seed,
                    &cable_servo::identify::SynthOptions::default(),
                )
            });
            match result {
                Ok(log) => match cable_servo::io::benchlog::write_bench_log(&out, &log) {
                    Ok(()) => {
                        say!("{} samples written to {}", log.len(), out.display());
                        ExitCode::SUCCESS
                    }
                    Err(e) => {
                        tell!("error: {e}");
                        ExitCode::from(exit::OUTPUT)
                    }
                },
                Err(e) => {
                    tell!("error: {e}");
                    ExitCode::from(exit::INPUT)
                }
            }
        }
        Command::Merge {
            out,
            shards,
            force,
            partial,
        } => match cable_servo::io::merge::merge_files(&shards, &out, force, partial) {
            Ok(r) if r.complete() => {
                say!(
                    "{} cases merged into {} (complete: every shard present)",
                    r.rows,
                    out.display()
                );
                ExitCode::SUCCESS
            }
            Ok(r) => {
                say!(
                    "PARTIAL merge: {} of {} cases in {}",
                    r.rows,
                    r.cases_total
                        .map_or_else(|| "an unknown number of".to_string(), |n| n.to_string()),
                    out.display()
                );
                for g in &r.gaps {
                    tell!("warning: partial merge: {g}");
                }
                ExitCode::SUCCESS
            }
            Err(e) => {
                tell!("error: {e}");
                ExitCode::from(e.exit_code())
            }
        },
        Command::Margins {
            scenario,
            set,
            load_nm,
            out,
            force,
        } => {
            let name = scenario.as_deref().unwrap_or(DEFAULT_SCENARIO);
            let scenario = match load(name, &set) {
                Ok(s) => s,
                Err(code) => return code,
            };
            let Some(p) = scenario.closed_loop.as_ref() else {
                return not_closed_loop(name);
            };
            if let Err(e) = run::check_load_nm(load_nm) {
                return report(Err(e));
            }
            say!(
                "{}: computation delay {} sample(s) at {} Hz",
                scenario.name(),
                cable_servo::compact(p.controller.computation_delay_samples),
                cable_servo::compact(p.controller.sample_rate_hz)
            );
            let dir = out.unwrap_or_else(|| {
                run::default_results_dir(
                    &PathBuf::from("results").join(format!("{}-margins", scenario.name())),
                    force,
                )
            });
            match run::run_margins(&scenario, load_nm, &OutputOptions { dir, force }) {
                Ok(r) => {
                    for w in &r.warnings {
                        tell!("warning: {w}");
                    }
                    match &r.explored {
                        Some((points, problem)) => {
                            say_raw!("{}", cable_servo::analysis::verdict::range_table(points));
                            if let Some(problem) = problem {
                                say!(
                                    "no tangent at --load-nm {}: {problem}",
                                    cable_servo::compact(load_nm.unwrap_or(0.0))
                                );
                            }
                            say!(
                                "(--load-nm explores another load; the verdict below is the design's as declared, at its operating load of {} N m)",
                                cable_servo::compact(r.judged_load_nm)
                            );
                        }
                        None => say_raw!("{}", r.verdict.range_table()),
                    }
                    say_raw!("{}", r.verdict.table());
                    say!("results: {}", r.dir.display());
                    verdict_code(r.verdict.passes)
                }
                Err(e) => report(Err(e)),
            }
        }
        Command::Freqresp {
            scenario,
            point,
            amplitudes,
            frequencies,
            f_min,
            f_max,
            points,
            operating_point,
            slew_rate,
            threads,
            out,
            set,
            force,
        } => {
            let name = scenario.as_deref().unwrap_or(DEFAULT_SCENARIO);
            let scenario = match load(name, &set) {
                Ok(s) => s,
                Err(code) => return code,
            };
            let mut spec = scenario
                .closed_loop
                .as_ref()
                .and_then(|c| c.freqresp.clone())
                .unwrap_or_default();
            if let Some(point) = point {
                match cable_servo::analysis::freqresp::LoopPoint::parse(&point) {
                    Ok(p) => spec.point = p,
                    Err(e) => {
                        tell!("error: --point: {e}");
                        return ExitCode::from(exit::INPUT);
                    }
                }
            }
            if !amplitudes.is_empty() {
                spec.amplitudes = amplitudes;
            }
            if !frequencies.is_empty() {
                spec.frequencies_hz = frequencies;
            }
            if let Some(f) = f_min {
                spec.f_min_hz = f;
                spec.frequencies_hz.clear();
            }
            if let Some(f) = f_max {
                spec.f_max_hz = Some(f);
                spec.frequencies_hz.clear();
            }
            if let Some(n) = points {
                spec.points = n;
                spec.frequencies_hz.clear();
            }
            if let Some(o) = operating_point {
                match cable_servo::analysis::freqresp::OperatingPoint::parse(&o) {
                    Ok(o) => spec.operating_point = Some(o),
                    Err(e) => {
                        tell!("error: --operating-point: {e}");
                        return ExitCode::from(exit::INPUT);
                    }
                }
            }
            if slew_rate.is_some() {
                spec.slew_rate_rad_s = slew_rate;
                // A slew rate asks for a slew.
                spec.operating_point
                    .get_or_insert(cable_servo::analysis::freqresp::OperatingPoint::Slewing);
            }
            let dir = out.unwrap_or_else(|| {
                run::default_results_dir(
                    &PathBuf::from("results").join(format!("{}-freqresp", scenario.name())),
                    force,
                )
            });
            let bar = indicatif::ProgressBar::new(0);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{elapsed_precise} [{bar:40}] {pos}/{len} measurements (eta {eta})",
                )
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            if let Some(p) = scenario.closed_loop.as_ref() {
                let n = spec
                    .frequencies(p.controller.sample_rate_hz)
                    .map_or(0, |f| f.len())
                    * spec
                        .amplitudes(p.motor.command_limit())
                        .map_or(0, |a| a.len());
                bar.set_length(n as u64);
            }
            let tick = || bar.inc(1);
            let result = run::run_freqresp(
                &scenario,
                &spec,
                sane_threads(threads),
                &OutputOptions { dir, force },
                &tick,
            );
            bar.finish_and_clear();
            match result {
                Ok(r) => {
                    for w in &r.warnings {
                        tell!("warning: {w}");
                    }
                    say!(
                        "{}: {} at the {} ({} runs, {:.1} s simulated)",
                        scenario.name(),
                        spec.point.transfer(),
                        spec.point.name(),
                        r.runs.0,
                        r.runs.1
                    );
                    say_raw!("{}", r.table);
                    say!("results: {}", r.dir.display());
                    if !r.passes {
                        say!("measured: a requirement is not met at some amplitude (see the table above); the design's verdict below is judged on the exact linear reference over the operating range and the simulated pointing error");
                    }
                    if r.unresolved > 0 {
                        say!("{} measurement(s) could not be resolved at their amplitude and are left out of its estimate (listed above and in freqresp.csv with their reason; a larger amplitude resolves them)", r.unresolved);
                    }
                    say!("design verdict:");
                    say_raw!("{}", r.verdict.table());
                    if !r.complete {
                        // A stopped run is a failing case, whatever the verdict of the
                        // design's own run.
                        tell!("frequency response INCOMPLETE: a measurement run stopped (listed in freqresp.csv with its reason); exit 4");
                        return ExitCode::from(exit::PHYSICAL);
                    }
                    verdict_code(r.verdict.passes)
                }
                Err(e) => report(Err(e)),
            }
        }
        Command::ExportFmu {
            scenario,
            out,
            set,
            library,
            force,
        } => {
            let scenario = match load(&scenario, &set) {
                Ok(s) => s,
                Err(code) => return code,
            };
            let library = match library {
                Some(l) => l,
                None => match std::env::current_exe() {
                    Ok(exe) => cable_servo::fmu::export::library_beside(&exe),
                    Err(e) => {
                        tell!("error: cannot locate this executable to find the shared library ({e}); give --library PATH");
                        return ExitCode::from(exit::INPUT);
                    }
                },
            };
            use cable_servo::fmu::export::{export_fmu, ExportError};
            match export_fmu(&scenario, &library, &out, force) {
                Ok(r) => {
                    say!(
                        "FMU written: {} ({} variables, {} bytes, GUID {})",
                        r.path.display(),
                        r.variables,
                        r.bytes,
                        r.guid
                    );
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    tell!("error: {e}");
                    ExitCode::from(match e {
                        ExportError::Exists(_) | ExportError::Io { .. } => exit::OUTPUT,
                        _ => exit::INPUT,
                    })
                }
            }
        }
        Command::Show { name } => match cable_servo::scenario::builtin(&name) {
            Some(text) => {
                say_raw!("{text}");
                ExitCode::SUCCESS
            }
            None => {
                let names: Vec<&str> = cable_servo::scenario::BUILTIN.iter().map(|b| b.0).collect();
                tell!(
                    "error: no built-in scenario {name:?}; built-in: {}",
                    names.join(", ")
                );
                ExitCode::from(exit::INPUT)
            }
        },
    }
}

/// `report.html` into a design command's results directory, already in place; like a
/// plot it never breaks the command: a failure is a warning.
fn html_report(dir: &std::path::Path) {
    if let Err(e) = cable_servo::report::html::write_report(dir) {
        tell!(
            "warning: {} not written: {e}",
            cable_servo::report::html::REPORT_FILE
        );
    }
}

/// Mode and load-feedforward choice of a tune from their command-line words.
fn tune_choices(
    mode: Option<&str>,
    feedforward: &str,
) -> Result<
    (
        Option<cable_servo::closed_loop::CompensationMode>,
        cable_servo::design::tune::Feedforward,
    ),
    String,
> {
    use cable_servo::closed_loop::CompensationMode;
    use cable_servo::design::tune::Feedforward;
    let mode = match mode {
        None => None,
        Some("none") => Some(CompensationMode::None),
        Some("memoryless") => Some(CompensationMode::Memoryless),
        Some("memory") => Some(CompensationMode::Memory),
        Some(other) => return Err(format!("--mode {other}: use none, memoryless or memory")),
    };
    let ff = match feedforward {
        "off" => Feedforward::Without,
        "on" => Feedforward::With,
        "both" => Feedforward::Both,
        other => return Err(format!("--feedforward {other}: use off, on or both")),
    };
    Ok((mode, ff))
}

/// `--filters derivative,notch,lead-lag` (or `none`).
fn filter_choices(list: &str) -> Result<cable_servo::design::tune::FilterSearch, String> {
    let mut f = cable_servo::design::tune::FilterSearch::default();
    for word in list.split(',').map(str::trim) {
        match word {
            "none" | "" => {}
            "derivative" => f.derivative = true,
            "notch" => f.notch = true,
            "lead-lag" => f.lead_lag = true,
            other => {
                return Err(format!(
                    "--filters {list}: `{other}` is not a filter; use derivative, notch, lead-lag (comma-separated) or none"
                ))
            }
        }
    }
    Ok(f)
}

/// A progress bar on stderr for a tune's stages (hidden when stderr is not a terminal).
fn tune_bar() -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(1);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar
}

/// `design tune`: tune, print the report, write the files; exit 0 when the pick meets
/// every requirement, 4 when it does not or nothing is signable.
#[allow(clippy::too_many_arguments)]
fn design_tune(
    scenario: Option<String>,
    rate: Option<f64>,
    (mode, feedforward, filters): (Option<&str>, &str, &str),
    quick: bool,
    out: Option<PathBuf>,
    force: bool,
    set: Vec<String>,
) -> ExitCode {
    use cable_servo::design::tune::tune;
    let filters = match filter_choices(filters) {
        Ok(f) => f,
        Err(msg) => {
            tell!("error: {msg}");
            return ExitCode::from(exit::USAGE);
        }
    };
    let (scenario, mut options) = match tune_setup(scenario, rate, mode, feedforward, quick, &set) {
        Ok(v) => v,
        Err(code) => return code,
    };
    options.filters = filters;
    let bar = tune_bar();
    let result = tune(&scenario, &options, &|p| {
        if bar.length() != Some(p.total as u64) {
            bar.set_length(p.total as u64);
            bar.set_message(p.stage);
        }
        bar.set_position(p.done as u64);
    });
    bar.finish_and_clear();
    let r = match result {
        Ok(r) => r,
        Err(e) => {
            tell!("error: {e}");
            return ExitCode::from(exit::INPUT);
        }
    };
    say_raw!("{}", cable_servo::design::tune_files::tune_text(&r));
    let dir = out.unwrap_or_else(|| {
        run::default_results_dir(
            &PathBuf::from("results").join(format!("{}-tune", scenario.name())),
            force,
        )
    });
    match cable_servo::design::tune_files::write_tune(&r, &scenario, &dir, force) {
        Ok(path) => {
            say!("results: {}", path.display());
            html_report(&path);
        }
        Err(e) => {
            tell!("error: {e}");
            return ExitCode::from(exit::OUTPUT);
        }
    }
    verdict_code(r.picked().is_some_and(|c| c.passes))
}

/// The scenario and search of `design tune` and `design least-rate` from their arguments;
/// the exit code of a usage or input error otherwise.
fn tune_setup(
    scenario: Option<String>,
    rate_hz: Option<f64>,
    mode: Option<&str>,
    feedforward: &str,
    quick: bool,
    set: &[String],
) -> Result<(Scenario, cable_servo::design::tune::TuneOptions), ExitCode> {
    use cable_servo::design::tune::{SearchSize, TuneOptions};
    let (asked, feedforward) = tune_choices(mode, feedforward).map_err(|msg| {
        tell!("error: {msg}");
        ExitCode::from(exit::USAGE)
    })?;
    let scenario = load(scenario.as_deref().unwrap_or("eots_tracking"), set)?;
    // The tuned design is judged in the mode its requirements declare, as every command
    // judges it: a --mode that differs would tune, and write out, another requirement.
    let judged = scenario.closed_loop.as_ref().map(|c| c.judged_mode());
    let declared = scenario
        .closed_loop
        .as_ref()
        .and_then(|c| c.requirements.mode);
    let mode = match (asked, declared) {
        (Some(a), Some(d)) if a != d => {
            tell!(
                "error: --mode {}: the scenario declares closed_loop.requirements.mode = \"{}\"; drop --mode, or declare the mode to judge (--set closed_loop.requirements.mode={})",
                a.name(),
                d.name(),
                a.name()
            );
            return Err(ExitCode::from(exit::USAGE));
        }
        (Some(a), _) => a,
        (None, _) => judged.unwrap_or(cable_servo::closed_loop::CompensationMode::Memory),
    };
    let search = if quick {
        SearchSize::reduced()
    } else {
        SearchSize::full()
    };
    Ok((
        scenario,
        TuneOptions {
            rate_hz,
            mode,
            feedforward,
            search,
            seeds_from: Vec::new(),
            filters: Default::default(),
        },
    ))
}

/// `design least-rate`: bisect over the control rate with a tune at each probe.
#[allow(clippy::too_many_arguments)]
fn design_least_rate(
    scenario: Option<String>,
    mode: Option<&str>,
    feedforward: &str,
    (min_hz, max_hz, tol_hz): (f64, f64, f64),
    quick: bool,
    out: Option<PathBuf>,
    force: bool,
    set: Vec<String>,
) -> ExitCode {
    use cable_servo::design::tune::least_rate;
    let (scenario, options) = match tune_setup(scenario, None, mode, feedforward, quick, &set) {
        Ok(v) => v,
        Err(code) => return code,
    };
    let bar = tune_bar();
    let result = least_rate(&scenario, &options, (min_hz, max_hz), tol_hz, &|rate, p| {
        if bar.length() != Some(p.total as u64) {
            bar.set_length(p.total as u64);
        }
        bar.set_message(format!("{} at {} Hz", p.stage, cable_servo::compact(rate)));
        bar.set_position(p.done as u64);
    });
    bar.finish_and_clear();
    let r = match result {
        Ok(r) => r,
        Err(e) => {
            tell!("error: {e}");
            return ExitCode::from(exit::INPUT);
        }
    };
    say_raw!("{}", cable_servo::design::tune_files::least_rate_text(&r));
    let dir = out.unwrap_or_else(|| {
        run::default_results_dir(
            &PathBuf::from("results").join(format!("{}-least-rate", scenario.name())),
            force,
        )
    });
    match cable_servo::design::tune_files::write_least_rate(&r, &scenario, &dir, force) {
        Ok(path) => {
            say!("results: {}", path.display());
            html_report(&path);
        }
        Err(e) => {
            tell!("error: {e}");
            return ExitCode::from(exit::OUTPUT);
        }
    }
    verdict_code(r.passing_hz.is_some())
}

/// Closed-loop design answer: bisect, print the value with its definition.
fn closed_loop_answer(
    search: &TargetSearch,
    default_scenario: &str,
    question: cable_servo::design::Question,
    (min, max, tol): (f64, f64, f64),
) -> ExitCode {
    use cable_servo::closed_loop::CompensationMode;
    let (min, max, tol) = (
        search.min.unwrap_or(min),
        search.max.unwrap_or(max),
        search.tol.unwrap_or(tol),
    );
    if let Err(e) = cable_servo::design::check_search((min, max), tol) {
        tell!("error: --min/--max/--tol: {e}");
        return ExitCode::from(exit::USAGE);
    }
    let name = search.scenario.as_deref().unwrap_or(default_scenario);
    let set = &search.set;
    let mode = match search.mode.as_str() {
        "none" => CompensationMode::None,
        "memoryless" => CompensationMode::Memoryless,
        "memory" => CompensationMode::Memory,
        other => {
            tell!("error: --mode {other}: use none, memoryless or memory");
            return ExitCode::from(exit::USAGE);
        }
    };
    let mut scenario = match load(name, set) {
        Ok(s) => s,
        Err(code) => return code,
    };
    let Some(cl) = scenario.closed_loop.as_mut() else {
        return not_closed_loop(name);
    };
    // The design is judged in the mode asked about, as every command judges it with
    // `closed_loop.requirements.mode` set to that mode.
    if !cl.modes.contains(&mode) {
        tell!(
            "error: --mode {}: {name} does not simulate it; list it in closed_loop.modes",
            mode.name()
        );
        return ExitCode::from(exit::INPUT);
    }
    cl.requirements.mode = Some(mode);
    let verdict = verdict_exit(&scenario, Some("the design as given:"), false);
    match cable_servo::design::largest_meeting_target(&scenario, question, mode, (min, max), tol) {
        Ok(a) => {
            match a.value {
                Some(v) => say!(
                    "{} {} (-{} {}, {} closed-loop runs)",
                    cable_servo::significant(v, 6),
                    a.unit,
                    cable_servo::compact(a.tolerance),
                    a.unit,
                    a.runs
                ),
                None => say!(
                    "none: even {} {} misses the target",
                    cable_servo::number(min),
                    a.unit
                ),
            }
            if let Some(note) = &a.note {
                say!("  note: {note}");
            }
            say!("  definition: {}", a.definition);
            if a.value.is_none() {
                ExitCode::from(exit::PHYSICAL)
            } else {
                verdict
            }
        }
        Err(e) => {
            tell!("error: {e}");
            ExitCode::from(exit::INPUT)
        }
    }
}

/// Judge a closed-loop design (simulating its judged mode), print the operating range's
/// crossings when asked and the verdict table; the exit code every command shares: 0 when
/// every requirement is met, 4 when one is not, 3 when the design cannot be judged.
fn verdict_exit(scenario: &Scenario, heading: Option<&str>, crossings: bool) -> ExitCode {
    use cable_servo::closed_loop::ClosedLoopSource;
    let setup = match scenario.closed_loop_setup() {
        Ok(s) => s,
        Err(e) => {
            tell!("error: {e}");
            return ExitCode::from(exit::INPUT);
        }
    };
    match cable_servo::analysis::verdict::evaluate(&setup) {
        Ok(v) => {
            if let Some(h) = heading {
                say!("{h}");
            }
            if crossings {
                say_raw!("{}", v.range_table());
            }
            say_raw!("{}", v.table());
            verdict_code(v.passes)
        }
        Err(e) => {
            tell!("error: {e}");
            ExitCode::from(exit::INPUT)
        }
    }
}

/// 0 when every requirement is met, 4 when one is not.
fn verdict_code(passes: bool) -> ExitCode {
    if passes {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(exit::PHYSICAL)
    }
}

/// Worker threads as asked, at most four per core: more only queue for the same cores,
/// and an absurd count would exhaust the process before any work starts.
fn sane_threads(asked: usize) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let most = 4 * cores;
    if asked > most {
        tell!("note: --threads {asked} lowered to {most} (four per core on this machine's {cores} cores)");
        most
    } else {
        asked
    }
}

/// `compare`: build the designs, run them, report; exit 4 when one fails its requirements.
fn compare(
    scenarios: Vec<String>,
    designs: Vec<String>,
    mode: Option<String>,
    set: Vec<String>,
    out: Option<PathBuf>,
    force: bool,
) -> ExitCode {
    let mode = match mode.as_deref() {
        None => None,
        Some(m) => match m {
            "none" => Some(cable_servo::closed_loop::CompensationMode::None),
            "memoryless" => Some(cable_servo::closed_loop::CompensationMode::Memoryless),
            "memory" => Some(cable_servo::closed_loop::CompensationMode::Memory),
            other => {
                tell!("error: --mode {other:?}: allowed are none, memoryless, memory");
                return ExitCode::from(exit::USAGE);
            }
        },
    };
    let valid_name = |n: &str| {
        !n.is_empty()
            && n.chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
            && !n.starts_with('.')
    };
    let mut list = Vec::new();
    if designs.is_empty() {
        if scenarios.is_empty() {
            tell!("error: compare needs designs: two or more scenarios, or one scenario with --design NAME:KEY=VALUE;...");
            return ExitCode::from(exit::USAGE);
        }
        for name in &scenarios {
            let scenario = match load(name, &set) {
                Ok(s) => s,
                Err(code) => return code,
            };
            list.push(run::CompareDesign {
                name: scenario.name().to_string(),
                description: name.clone(),
                scenario,
            });
        }
    } else {
        if scenarios.len() > 1 {
            tell!(
                "error: with --design give one base scenario, not {}",
                scenarios.len()
            );
            return ExitCode::from(exit::USAGE);
        }
        let base = scenarios.first().map_or(DEFAULT_SCENARIO, String::as_str);
        for d in &designs {
            let Some((name, sets)) = d.split_once(':') else {
                tell!("error: --design {d:?}: write NAME:KEY=VALUE;KEY=VALUE (NAME alone runs the base as is: NAME:)");
                return ExitCode::from(exit::USAGE);
            };
            let name = name.trim();
            if !valid_name(name) {
                tell!("error: --design {d:?}: the name {name:?} must be letters, digits, '-', '_' or '.' (it names a folder)");
                return ExitCode::from(exit::USAGE);
            }
            let mut all = set.clone();
            all.extend(
                sets.split(';')
                    .map(str::trim)
                    .filter(|s| !s.is_empty())
                    .map(str::to_string),
            );
            let scenario = match load(base, &all) {
                Ok(s) => s,
                Err(code) => {
                    tell!("  (in --design {name}:{sets})");
                    return code;
                }
            };
            list.push(run::CompareDesign {
                name: name.to_string(),
                description: if sets.trim().is_empty() {
                    format!("{base} as is")
                } else {
                    format!("{base} with {}", sets.trim())
                },
                scenario,
            });
        }
    }
    let dir = out.unwrap_or_else(|| {
        run::default_results_dir(&PathBuf::from("results").join("compare"), force)
    });
    match run::run_compare(&list, mode, &OutputOptions { dir, force }) {
        Ok(c) => {
            let passing = c.passing;
            let total = c.designs;
            let code = report(Ok(c.run));
            if passing == total {
                say!("every design meets every requirement ({total} of {total})");
                code
            } else {
                tell!(
                    "{} of {total} designs miss a requirement (a design that stopped counts as missing it)",
                    total - passing
                );
                if code == ExitCode::SUCCESS {
                    ExitCode::from(exit::PHYSICAL)
                } else {
                    code
                }
            }
        }
        Err(e) => report(Err(e)),
    }
}

/// A command that needs a closed loop was given scenario `name` without one.
fn not_closed_loop(name: &str) -> ExitCode {
    tell!("error: {name} is not a closed-loop scenario (study = \"closed_loop\")");
    ExitCode::from(exit::INPUT)
}

fn load(name: &str, set: &[String]) -> Result<Scenario, ExitCode> {
    let mut scenario = Scenario::load(name, set).map_err(|e| {
        tell!("error: {e}");
        ExitCode::from(exit::INPUT)
    })?;
    let base = std::path::Path::new(name)
        .parent()
        .map(std::path::Path::to_path_buf)
        .unwrap_or_default();
    cable_servo::io::tables::load_tables(&mut scenario, &base).map_err(|e| {
        // The table's own message names the CSV; the scenario that refers to it is named too.
        tell!("error: {name}: {e}");
        ExitCode::from(exit::INPUT)
    })?;
    Ok(scenario)
}

fn report(result: Result<RunReport, RunError>) -> ExitCode {
    match result {
        Ok(r) => {
            for w in &r.warnings {
                tell!("warning: {w}");
            }
            say_raw!("{}", r.table);
            say!("results: {}", r.dir.display());
            if let Some(sig) = r.signal {
                tell!("error: {}", r.failure.as_deref().unwrap_or("interrupted"));
                tell!("results kept, marked INCOMPLETE: {}", r.dir.display());
                return ExitCode::from(cable_servo::io::signals::exit_code(sig));
            }
            match (&r.failure, r.requirements_met) {
                (Some(f), _) => {
                    tell!("error: run incomplete (results kept, marked INCOMPLETE): {f}");
                    ExitCode::from(exit::PHYSICAL)
                }
                (None, Some(false)) => ExitCode::from(exit::PHYSICAL),
                (None, _) => ExitCode::SUCCESS,
            }
        }
        Err(e) => {
            tell!("error: {e}");
            ExitCode::from(match e {
                // A result file that cannot be written is an output fault, whichever
                // part of the run writes it.
                RunError::Identify(cable_servo::identify::IdentifyError::Write { .. }) => {
                    exit::OUTPUT
                }
                RunError::Scenario(_)
                | RunError::Table(_)
                | RunError::Sweep(_)
                | RunError::ClosedLoop(_)
                | RunError::Identify(_)
                | RunError::Log(_)
                | RunError::FreqResp(_)
                | RunError::Unsupported(_) => exit::INPUT,
                RunError::Output(_) | RunError::Report(_) => exit::OUTPUT,
            })
        }
    }
}
