//! `imu-emu`: the command-line front end. Flags and files here; everything else in the library.

mod cmd;

use clap::{Parser, Subcommand};

use imu_emu::scenes;

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
    Generate(Box<cmd::setup::GenerateArgs>),
    /// Write a scene's reference trajectory as trajectory CSV (the input format).
    Trajectory(cmd::info::TrajectoryArgs),
    /// List the built-in scenes.
    Scenes,
    /// List the built-in IMU templates with their headline figures.
    Templates,
    /// Decode a frame stream (file or stdin) to CSV, counting check failures and counter gaps.
    Decode(cmd::decode::DecodeArgs),
    /// Statistics, Allan deviation with fitted IEEE terms, and PSD of a recording, with plots.
    Analyze(Box<cmd::analyze::AnalyzeArgs>),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Generate(a) => cmd::generate::generate(*a),
        Command::Trajectory(a) => cmd::info::export_trajectory(a),
        Command::Templates => cmd::info::list_templates(),
        Command::Decode(a) => cmd::decode::decode(a),
        Command::Analyze(a) => cmd::analyze::analyze(*a),
        Command::Scenes => {
            for name in scenes::NAMES {
                println!(
                    "{name}{}",
                    if name == scenes::DEFAULT {
                        " (default)"
                    } else {
                        ""
                    }
                );
            }
            Ok(())
        }
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
