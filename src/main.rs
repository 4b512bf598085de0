//! `imu-emu`: the command-line front end. Flags and files here; everything else in the library.

mod cmd;

use std::io::Write;

use clap::{Parser, Subcommand};

use imu_emu::output::failure::ReaderLeft;
use imu_emu::scenes;

/// Exit status when standard output, the only output, lost its reader: 128 + SIGPIPE.
const READER_LEFT: i32 = 128 + 13;

/// IMU simulator and emulator: error-free and corrupted inertial signals from a trajectory.
#[derive(Parser)]
#[command(name = "imu-emu", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Generate IMU records offline, as fast as the machine allows.
    Generate(Box<cmd::generate::GenerateArgs>),
    /// Write a scene's reference trajectory as trajectory CSV (the input format).
    Trajectory(cmd::info::TrajectoryArgs),
    /// List the built-in scenes.
    Scenes,
    /// List the built-in IMU templates with their headline figures.
    Templates,
    /// Emulate the IMU in real time: frames at wall-clock rate to ptys, serial, UDP, files.
    Run(Box<cmd::run::RunArgs>),
    /// Decode a frame stream (file or stdin) to CSV, counting check failures, counter gaps,
    /// duplicates, stale counters and status failures.
    Decode(cmd::decode::DecodeArgs),
    /// Validate the simulator (paper §4): error-free signal, navigator closure, noise terms.
    Validate(cmd::validate::ValidateArgs),
    /// Navigate records free-inertially from a reference's initial state; trajectory and errors.
    Navigate(cmd::navigate::NavigateArgs),
    /// Compare IMU templates by Monte Carlo free-inertial navigation error over a scene.
    Compare(cmd::compare::CompareArgs),
    /// Statistics, Allan deviation with fitted IEEE terms, and PSD of a recording, with plots.
    Analyze(Box<cmd::analyze::AnalyzeArgs>),
    /// Plot the injected error components of a --truth-errors file over time, per sensor axis.
    PlotErrors(cmd::plot_errors::PlotErrorsArgs),
    /// Fit a template to a static recording: noise terms with intervals, report, closure check.
    Fit(Box<cmd::fit::FitArgs>),
}

fn main() {
    let cli = Cli::try_parse().unwrap_or_else(|e| clap_exit(e));
    let result = match cli.command {
        Command::Generate(a) => cmd::generate::generate(*a),
        Command::Trajectory(a) => cmd::info::export_trajectory(a),
        Command::Templates => cmd::info::list_templates(),
        Command::Decode(a) => cmd::decode::decode(a),
        Command::Validate(a) => cmd::validate::validate(a),
        Command::Navigate(a) => cmd::navigate::navigate(a),
        Command::Compare(a) => cmd::compare::compare(a),
        Command::Run(a) => cmd::run::run(*a),
        Command::Analyze(a) => cmd::analyze::analyze(*a),
        Command::PlotErrors(a) => cmd::plot_errors::plot_errors(a),
        Command::Fit(a) => cmd::fit::fit(*a),
        Command::Scenes => list_scenes(),
    };
    if let Err(e) = result {
        // Standard output was the only output and its reader left (`… | head`): nothing is
        // said, and the status is that of a command killed by SIGPIPE, so that a shell's
        // `pipefail` still sees an output that was not written whole.
        if e.chain().any(|c| c.is::<ReaderLeft>()) {
            std::process::exit(READER_LEFT);
        }
        // A command stopped by a signal has said so; only the exit status is left to give.
        if let Some(i) = e.downcast_ref::<imu_emu::realtime::signal::Interrupted>() {
            std::process::exit(i.exit_code());
        }
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

/// `imu-emu scenes`: written, not printed, so that a full disk or a closed pipe is an error
/// the caller sees rather than a panic.
fn list_scenes() -> anyhow::Result<()> {
    let mut text = String::new();
    for name in scenes::NAMES {
        let default = if name == scenes::DEFAULT {
            " (default)"
        } else {
            ""
        };
        text += &format!("{name}{default}\n");
    }
    cmd::stdout::write(text.as_bytes(), "the scenes", true)
}

/// Prints clap's help, version or usage error and exits with its status; a help that could
/// not be written is an error (exit 1: `--help > /dev/full` is no success), and into a reader
/// that stopped early (`--help | head`) ends quietly with 141, as any command's only output.
fn clap_exit(e: clap::Error) -> ! {
    match e.print().and_then(|()| std::io::stdout().flush()) {
        Ok(()) => std::process::exit(e.exit_code()),
        Err(io) if io.kind() == std::io::ErrorKind::BrokenPipe => std::process::exit(READER_LEFT),
        Err(io) => {
            eprintln!("error: writing the help: {io}");
            std::process::exit(1);
        }
    }
}
