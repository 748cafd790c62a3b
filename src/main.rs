//! `gema2`: the user-facing command line.
//!
//! One job: the commands a user types, each a thin module in `cmd` over the libraries, and the
//! supervisor of the pipeline (`supervisor`). With no command it runs the pipeline on the
//! embedded default. Depends on every library crate but `viewer`, whose program it starts.

mod cmd;
mod diagnose;
mod progress;
mod report;
mod results;
mod sequential;
mod supervisor;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "gema2",
    version,
    about = "Fast global single-scan self-localization from a 2D laser (GEMA2)",
    long_about = "Fast global single-scan self-localization from a 2D laser (GEMA2).\n\nWith no command, runs \
                  the pipeline of processes on the embedded default (`gema2 run`): the simulator in the bundled \
                  office, 300 scans at 10 Hz, then prints each stage's and hop's latency and the success rate."
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Maps: list and export the bundled ones, generate procedural ones, inspect corners.
    #[command(subcommand)]
    Map(cmd::map::MapCommand),
    /// Simulate a laser in a map and write a ROBOTLASER1 log with the true poses.
    Sim(cmd::sim::SimArgs),
    /// Localize every scan of a log offline and report time and accuracy.
    Locate(Box<cmd::locate::LocateArgs>),
    /// Run the pipeline of separate processes over shared memory (supervisor).
    Run(supervisor::RunArgs),
    /// What a rerun recording of a run holds (through the `viewer` program).
    Inspect(cmd::inspect::InspectArgs),
    /// Replace a stage's implementation in a running pipeline.
    Swap(supervisor::swap::SwapArgs),
    /// An emulated Hokuyo lidar speaking SCIP 2.0: a URG-04LX on a pseudo-terminal (prints its
    /// path), or a UST-10LX, UTM-30LX or URG-04LX on TCP (`--tcp`, prints its address).
    EmulateUrg(cmd::emulate::EmulateArgs),
    /// Segmentation alone over a log: lines and corners per scan, time per scan.
    Lines(cmd::lines::LinesArgs),
    #[command(subcommand, about = STAGE_ABOUT)]
    Stage(StageCommand),
    /// The algorithm on the bundled office with simulated scans, in one process.
    Demo(cmd::demo::DemoArgs),
    /// Time each stage per scan and print how locate scales with beams and map walls.
    Bench(cmd::bench::BenchArgs),
    /// How far a log's odometry strays from its true poses: the motion model's four alphas,
    /// for the sequential localizer's `odom_alpha1`..`odom_alpha4`. Fit at the `--every` the
    /// scans are located at: odometry's errors add up over the scans between.
    Odometry(cmd::odometry::OdometryArgs),
    /// Every key `--set` takes, with its default, range and meaning, grouped by stage.
    Settings(cmd::settings::SettingsArgs),
    /// Success over a suite of simulated logs (bundled and generated maps, every scenario) and
    /// optionally real logs: the README's accuracy figures from one command.
    Evaluate(cmd::evaluate::EvaluateArgs),
    /// Nav2's AMCL (PyPI `amcl`) and the sequential localizer side by side from a global start:
    /// scans, metres and seconds until each pose is right and stays right.
    Amcl(Box<cmd::amcl::AmclArgs>),
}

/// `gema2 stage ...` parsed alone: a pipeline process builds the parser of its own stage, not
/// the whole tool's, whose freed pages would stay in its heap for the life of the process.
#[derive(Parser)]
#[command(name = "gema2 stage", bin_name = "gema2 stage", version, about = STAGE_ABOUT)]
struct StageCli {
    #[command(subcommand)]
    stage: StageCommand,
}

/// `gema2 stage`'s description, in the tool's help and its own.
const STAGE_ABOUT: &str = "Run one stage in this process (what `gema2 run` starts)";

#[derive(Subcommand)]
enum StageCommand {
    #[command(about = acquire::node::ABOUT)]
    Acquire(Box<acquire::node::AcquireArgs>),
    #[command(about = segment::node::ABOUT)]
    Segment(segment::node::SegmentArgs),
    #[command(about = localize::node::ABOUT)]
    Localize(localize::node::LocalizeArgs),
    #[command(about = mapserver::node::ABOUT)]
    Mapserver(mapserver::node::MapServerArgs),
    #[command(about = ros2::node::ABOUT)]
    Ros2(Box<ros2::node::Ros2Args>),
}

/// Lets a closed stdout end the process quietly, as it ends `ls` or `grep`: `gema2 map info M
/// | head -1` would otherwise panic on the broken pipe. Not for the pipeline's processes, which
/// handle their own signals and must not die with a consumer that stopped reading, nor for
/// `gema2 amcl`, whose worker dying must be an error that says so.
fn exit_quietly_on_a_closed_pipe() {
    // SAFETY: restoring a signal's default disposition, before any thread starts
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn run_stage(stage: StageCommand) -> anyhow::Result<()> {
    match stage {
        StageCommand::Acquire(a) => acquire::node::run(*a),
        StageCommand::Ros2(a) => ros2::node::run(*a),
        StageCommand::Segment(a) => segment::node::run(a),
        StageCommand::Localize(a) => localize::node::run(a),
        StageCommand::Mapserver(a) => mapserver::node::run(a),
    }
}

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args_os();
    if args.nth(1).is_some_and(|a| a == "stage") {
        return run_stage(StageCli::parse_from(std::iter::once("gema2 stage".into()).chain(args)).stage);
    }
    let cli = Cli::parse();
    if !matches!(
        cli.command,
        None | Some(Command::Run(_) | Command::Stage(_) | Command::EmulateUrg(_) | Command::Swap(_) | Command::Amcl(_))
    ) {
        exit_quietly_on_a_closed_pipe();
    }
    match cli.command {
        Some(Command::Map(c)) => cmd::map::run(c),
        Some(Command::Sim(a)) => cmd::sim::run(a),
        Some(Command::Locate(a)) => cmd::locate::run(*a),
        Some(Command::Bench(a)) => cmd::bench::run_bench(a),
        Some(Command::Demo(a)) => cmd::demo::run(a),
        Some(Command::Evaluate(a)) => cmd::evaluate::run(a),
        Some(Command::Amcl(a)) => cmd::amcl::run(*a),
        Some(Command::Settings(a)) => cmd::settings::run(a),
        Some(Command::Odometry(a)) => cmd::odometry::run(a),
        Some(Command::Run(a)) => supervisor::run(a),
        Some(Command::EmulateUrg(a)) => cmd::emulate::run(a),
        Some(Command::Lines(a)) => cmd::lines::run(a),
        Some(Command::Inspect(a)) => cmd::inspect::run(a),
        Some(Command::Swap(a)) => supervisor::swap::request(a),
        Some(Command::Stage(s)) => run_stage(s),
        None => supervisor::run(supervisor::RunArgs::default()),
    }
}

#[cfg(test)]
mod tests {
    use super::{Cli, StageCli};
    use clap::{CommandFactory, Parser};

    /// A pipeline process parses `gema2 stage ...` with its own parser ([`StageCli`]): it must
    /// take and refuse what the whole tool's does, and name itself as the whole tool does.
    #[test]
    fn a_stage_parses_alone_as_within_the_whole_tool() {
        StageCli::command().debug_assert();
        let argvs: [&[&str]; 7] = [
            &["localize", "--prefix", "p", "--cpu", "1"],
            &["segment", "--impl", "x"],
            &["mapserver", "--map", "office"],
            &["acquire", "--sim", "--no-such-flag"],
            &["localize", "--cpu", "one"],
            &["nonsense"],
            &[],
        ];
        for argv in argvs {
            let whole = Cli::try_parse_from(["gema2", "stage"].iter().chain(argv)).map(|_| ());
            let alone = StageCli::try_parse_from(["gema2 stage"].iter().chain(argv)).map(|_| ());
            assert_eq!(whole.map_err(|e| e.kind()), alone.map_err(|e| e.kind()), "gema2 stage {argv:?}");
        }
        assert!(StageCli::try_parse_from(["gema2 stage", "localize", "--prefix", "p"]).is_ok());
        let help = StageCli::try_parse_from(["gema2 stage", "localize", "--help"]).err().map(|e| e.to_string());
        assert!(help.is_some_and(|h| h.contains("Usage: gema2 stage localize")));
    }

    /// Where an `Args` struct's doc comment leaks into `--help` as a command's description
    /// (clap takes a flattened struct's doc when the command has none of its own), the text is
    /// written for Rust readers: `gema2 stage --help` once described three stages as "The
    /// arguments every stage process takes, declared once".
    #[test]
    fn every_command_describes_itself_for_a_user() {
        fn check(cmd: &clap::Command, path: &str, problems: &mut Vec<String>) {
            let mut seen = std::collections::HashMap::new();
            for sub in cmd.get_subcommands().filter(|s| s.get_name() != "help") {
                let here = format!("{path} {}", sub.get_name());
                let about = sub.get_about().map(|a| a.to_string()).unwrap_or_default();
                if about.is_empty() {
                    problems.push(format!("{here}: no description"));
                }
                if about.contains("[`") || about.contains("declared once") {
                    problems.push(format!("{here}: a doc comment for Rust readers: {about:?}"));
                }
                if let Some(other) = seen.insert(about.clone(), here.clone()) {
                    problems.push(format!("{here} and {other} share the description {about:?}"));
                }
                for arg in sub.get_arguments() {
                    let help = arg.get_help().map(|h| h.to_string()).unwrap_or_default();
                    if help.trim().is_empty()
                        && !arg.is_hide_set()
                        && !["help", "version"].contains(&arg.get_id().as_str())
                    {
                        problems.push(format!("{here} --{}: no help line", arg.get_id()));
                    }
                    if help.contains("[`") {
                        problems.push(format!("{here} --{}: rustdoc link in its help: {help:?}", arg.get_id()));
                    }
                }
                check(sub, &here, problems);
            }
        }
        let mut problems = Vec::new();
        check(&Cli::command(), "gema2", &mut problems);
        assert!(problems.is_empty(), "{problems:#?}");
    }
}
