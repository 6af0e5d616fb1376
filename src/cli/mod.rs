//! The `cdlab` command line. Each subcommand lives in its own file with an `Args` struct
//! (clap) and a `run` function; this file only dispatches. The work of running tests and
//! campaigns is the library's ([`crate::run`], [`crate::campaign`]): the subcommands parse,
//! call it and print, and their progress displays are implementations of its callbacks.

/// `eprintln!` for progress and the messages around a run or a campaign, which must never
/// stop it: a line that cannot be written (stderr on a full disk, a log whose file system
/// fails) is dropped. `eprintln!` panics there instead, and in a sweep's worker thread
/// that panic ended the whole campaign, leaving its other tests unstarted. What a command
/// exists to print (a table, a report) keeps `println!`, whose failure [`main`] turns into
/// exit code 1.
macro_rules! note {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

/// `println!` for the closing lines of a command whose work is done by then (a finished
/// run's table, a prepared sample's line): the work's files are complete whether or not the
/// line can be shown, so a stdout that refuses it (`>/dev/full`, a closed pipe) gets a
/// warning on stderr instead of failing the command.
macro_rules! tell {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = writeln!(std::io::stdout(), $($arg)*) {
            note!("warning: could not write to stdout: {e} (the command's work is done)");
        }
    }};
}

pub mod archive;
pub mod bands;
pub mod bench;
mod bench_report;
pub mod biaxial;
mod campaign_display;
mod campaign_messages;
pub mod compare;
pub mod config;
pub mod export;
pub mod fabric;
mod fabric_report;
pub mod fc2d;
pub mod info;
pub mod overlaps;
pub mod prepare;
pub mod render;
pub mod report;
pub mod run;
mod run_events;
pub mod summarize;
pub mod sweep;

use clap::{Parser, Subcommand};

/// cdlab: contact dynamics laboratory for granular materials of rigid frictional disks.
#[derive(Parser, Debug)]
#[command(name = "cdlab", version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Run the biaxial test (deposition, compaction, confinement, compression).
    Biaxial(biaxial::Args),
    /// Solve a Siconos 2D frictional contact problem (fc2d file).
    Fc2d(fc2d::Args),
    /// Deposit and compact a sample, to reuse it across tests (`biaxial --sample`).
    Prepare(prepare::Args),
    /// Analyse finished tests: Mohr-Coulomb envelopes, macroscopic friction.
    Report(report::Args),
    /// Run a friction x pressure campaign (`sweep FILE.toml [--shard I/N]`), or merge
    /// campaign directories into one report (`sweep collect DIR...`).
    Sweep(sweep::Args),
    /// Keep finished tests without their records (summary, configuration, thinned series):
    /// a campaign to store, move or resume elsewhere (`archive DIR... --to DEST`).
    Archive(archive::Args),
    /// Export a run's snapshots as VTK files (ParaView).
    Export(export::Args),
    /// Shear bands of a recorded run: angle from the axial direction, width in mean
    /// diameters (`bands RUN [--from E --to E]`).
    Bands(bands::Args),
    /// The deepest disk pairs of a recorded run's snapshots, with their forces and normal
    /// velocities (`overlaps RUN [--at STRAIN]`): which contact holds an overlap warning.
    Overlaps(overlaps::Args),
    /// The microstructure of a recorded run's snapshot: fabric and force anisotropies,
    /// strong network, Love-Weber stress, rose diagram and force PDF
    /// (`fabric RUN [--at STRAIN] [-o DIR]`).
    Fabric(fabric::Args),
    /// Write finished tests' summaries again from their records, as this version computes
    /// them (`summarize DIR... [--dry-run]`): tests finished by an older version.
    Summarize(summarize::Args),
    /// Draw a run's figures: a snapshot (`--at STRAIN --field NAME -o FIG.png|svg`) or the
    /// curves against axial strain (`--curves -o DIR`).
    Render(render::Args),
    /// Draw several runs' curves on common axes, sigma_1/sigma_3 and dV/V0 against axial
    /// strain (`compare RUN... -o FIG.png|svg`); runs may be archived tests.
    Compare(compare::Args),
    /// Measure time per step on the CPU and GPU paths (table, bench.json, bench.md).
    Bench(bench::Args),
    /// Print the version and build information.
    Version,
    /// Print the default configuration or check a configuration file.
    Config(config::Args),
    /// List the GPU adapters and their limits.
    Info(info::Args),
}

/// What `cdlab version` prints: the version, then the build's git commit ("-dirty" after
/// it when the sources it was built from had uncommitted changes), wgpu version,
/// target, profile and compiler (`unknown` for what the build could not find out, e.g. the
/// commit of a build outside a git checkout), one `key: value` line each.
pub fn build_info() -> String {
    format!(
        "cdlab {}\n\
         git commit: {} (at build time)\n\
         wgpu: {}\n\
         target: {}\n\
         profile: {}\n\
         compiler: {}\n",
        env!("CARGO_PKG_VERSION"),
        env!("CDLAB_GIT_COMMIT"),
        env!("CDLAB_WGPU_VERSION"),
        env!("CDLAB_TARGET"),
        env!("CDLAB_PROFILE"),
        env!("CDLAB_RUSTC"),
    )
}

/// Parses the command line, runs the subcommand and returns the process exit code.
///
/// A terminal or log that refuses writes (a full disk under a redirected stderr) makes Rust's
/// print macros panic. Every file a run writes is already safe at that point (written whole,
/// or a record that resumes), so such a panic ends the process with exit code 1 and no
/// backtrace, like any other error; every other panic is left as it is.
pub fn main() -> i32 {
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !is_print_failure(info.payload()) {
            default_hook(info);
        }
    }));
    match std::panic::catch_unwind(run_command) {
        Ok(code) => code,
        Err(payload) if is_print_failure(payload.as_ref()) => {
            // The hook kept the panic's text back; without it the exit code 1 came with
            // nothing on stderr (`cdlab report DIR >/dev/full`).
            note!("error: {}", panic_text(payload.as_ref()));
            1
        }
        Err(payload) => std::panic::resume_unwind(payload),
    }
}

/// Whether `command` does long work whose progress, printed on the way, must never stop it
/// (docs/reliability.md, "Progress never stops a run or a sweep"): a run, a resume, a
/// sample's preparation or a sweep. Those write nothing their work depends on to stdout or
/// stderr, and drop a line that cannot be written. Every other command prints what it
/// exists for, and a closed pipe (`cdlab report DIR | head`) ends it quietly.
fn keeps_running_on_closed_pipes(command: &Command) -> bool {
    match command {
        Command::Biaxial(_) | Command::Prepare(_) => true,
        Command::Sweep(args) => args.file.as_os_str() != "collect",
        _ => false,
    }
}

/// Makes a write into a closed pipe fail with EPIPE instead of ending the process:
/// `src/main.rs` gives SIGPIPE its default action, which killed a run or a sweep whose
/// progress went into `| head` (exit code 141) between two checkpoints.
fn ignore_closed_pipes() {
    #[cfg(unix)]
    // SAFETY: called before the command starts any thread; SIG_IGN is a valid disposition.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_IGN);
    }
}

/// Whether a panic is the print macros' "failed printing to stdout/stderr".
fn is_print_failure(payload: &(dyn std::any::Any + Send)) -> bool {
    panic_text(payload).starts_with("failed printing to std")
}

/// A panic's message ("failed printing to stdout: No space left on device (os error
/// 28)"), or "" when it has none.
fn panic_text(payload: &(dyn std::any::Any + Send)) -> &str {
    payload
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| payload.downcast_ref::<&str>().copied())
        .unwrap_or("")
}

fn run_command() -> i32 {
    let cli = Cli::parse();
    if keeps_running_on_closed_pipes(&cli.command) {
        ignore_closed_pipes();
    }
    let result: crate::Result<()> = match cli.command {
        Command::Biaxial(args) => biaxial::run(&args),
        Command::Fc2d(args) => fc2d::run(&args),
        Command::Prepare(args) => prepare::run(&args),
        Command::Report(args) => report::run(&args),
        Command::Sweep(args) => sweep::run(&args),
        Command::Archive(args) => archive::run(&args),
        Command::Export(args) => export::run(&args),
        Command::Bands(args) => bands::run(&args),
        Command::Overlaps(args) => overlaps::run(&args),
        Command::Fabric(args) => fabric::run(&args),
        Command::Summarize(args) => summarize::run(&args),
        Command::Render(args) => render::run(&args),
        Command::Compare(args) => compare::run(&args),
        Command::Bench(args) => bench::run(&args),
        Command::Version => {
            print!("{}", build_info());
            Ok(())
        }
        Command::Config(args) => config::run(&args),
        Command::Info(args) => info::run(&args),
    };
    // The exit code says how the command ended even when its last words cannot be written.
    match result {
        Ok(()) => 0,
        // 128 + the signal, as a shell reports a process the signal ended.
        Err(e @ crate::Error::Interrupted { signal, .. }) => {
            note!("{e}");
            128 + signal
        }
        Err(e) => {
            note!("error: {e}");
            if let Some(r) = e.remedy() {
                note!("help: {}", hint(&r));
            }
            1
        }
    }
}

/// What to do about an error ([`crate::Error::remedy`]), in this command line's words:
/// its commands and flags, which the library's messages leave out.
pub fn hint(remedy: &crate::error::Remedy) -> String {
    use crate::error::Remedy;
    match remedy {
        Remedy::Resume(dir) => format!("`cdlab biaxial --resume {}`", dir.display()),
        Remedy::StartAgain => "start the run again with --force".into(),
        Remedy::ReplaceResumeOrElsewhere(dir) => format!(
            "pass --force to replace them, --resume {} to continue that run, or --out DIR",
            dir.display()
        ),
        Remedy::PrepareAgain(file) => format!(
            "`cdlab prepare -o {} --force` with its settings (for a sweep, delete the file and \
             run the sweep again)",
            file.display()
        ),
        Remedy::Summarize(dir) => format!("`cdlab summarize {}`", dir.display()),
        Remedy::UseCpu => "rerun with --backend cpu, or continue the run on the CPU with \
             `cdlab biaxial --resume DIR --backend cpu`"
            .into(),
        Remedy::UseThinnedSeries(dir) => {
            format!(
                "`cdlab render {} --curves` draws from the thinned series",
                dir.display()
            )
        }
    }
}
