//! `slam-node`: the radar SLAM daemon.
//!
//! With no arguments it starts the simulator in this process (the shipped outdoor-field
//! scene on 127.0.0.1:0), runs the daemon against it for 60 s of simulated driving and
//! prints a summary against ground truth. With `--config vehicle.toml` it connects to the
//! radar and odometry the file names and runs until stopped. A vehicle build
//! (`--no-default-features`) links no simulator and needs `--config`. The flags and the
//! options they make are in `cli.rs`.

mod cli;

use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::Context;
use clap::Parser;
use slam_node::daemon::{report, run_daemon};

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn,slam_node=info")),
        )
        .with_writer(std::io::stderr)
        // Colour only on a terminal: a log written to a file or a pipe stays plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    match run(cli::Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("slam-node: {}", radar_driver::ErrorChain(e.as_ref()));
            ExitCode::FAILURE
        }
    }
}

fn run(args: cli::Args) -> anyhow::Result<()> {
    if args.lists_profiles() {
        return list_profiles();
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    // Ctrl-C and SIGTERM (what `kill`, systemd and container runtimes send), handled from
    // here on, before anything is read. Before the run begins (the configuration, a saved map
    // or a recording being read, the scene built, the simulator started, a Foxglove client
    // awaited) the run has produced nothing and those steps do not look at the stop flag: the
    // process ends at once, as the signal's default action would, after saying so. From then on the run ends the same
    // way for both: the pipeline drains, the outputs are written and the summary printed.
    let stop = Arc::new(AtomicBool::new(false));
    let stop_request = {
        let _runtime = runtime.enter();
        radar_driver::stop_signal()
    };
    let stop_flag = Arc::clone(&stop);
    runtime.spawn(async move {
        let why = stop_request.await;
        if slam_node::daemon::start::abandon_start() {
            eprintln!("slam-node: stopped ({why}) while starting up, before the run began");
            end_as_signalled(why);
        }
        eprintln!("slam-node: stopping ({why})");
        stop_flag.store(true, Ordering::Relaxed);
    });
    let mut opts = cli::options(&args)?;
    opts.stop = Arc::clone(&stop);
    let doing = args.doing();
    let stopped = stop;
    let every = opts.progress_every_rotations;
    let progress: Option<slam_node::pipeline::run::ProgressFn> = (every > 0).then(|| {
        Box::new(
            move |s: &slam_node::pipeline::PipelineSummary,
                  ekf: &slam_node::pipeline::DaemonEkf| {
                if s.rotations.is_multiple_of(every) {
                    eprintln!("{}", report::progress_line(s, ekf));
                }
            },
        ) as slam_node::pipeline::run::ProgressFn
    });
    let result = runtime.block_on(async move {
        // SIGUSR1: save the map now ([map] path), the run goes on.
        #[cfg(unix)]
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::user_defined1()) {
            Ok(mut usr1) => {
                tokio::spawn(async move {
                    while usr1.recv().await.is_some() {
                        eprintln!("slam-node: saving the map (SIGUSR1)");
                        slam_node::pipeline::saved_map::request_save();
                    }
                });
            }
            Err(e) => eprintln!("slam-node: SIGUSR1 will not save the map: {e}"),
        }
        run_daemon(opts, progress).await
    });
    if result.as_ref().is_err_and(|e| e.is_stopped_before_start()) {
        if slam_node::daemon::start::start_abandoned() {
            // The stop handler is ending the process (`end_as_signalled`): the status is its.
            loop {
                std::thread::park();
            }
        }
        // A stop flag set while the scene was built (not by this binary's handler, which ends
        // a stop before the run itself): do not wait for the abandoned build.
        runtime.shutdown_background();
        anyhow::bail!("stopped (Ctrl-C or SIGTERM) while building the scene, before the run began");
    }
    // The simulator's ground-truth writer may still be flushing on the blocking pool.
    runtime.shutdown_timeout(std::time::Duration::from_secs(2));
    let report = result.context(doing)?;
    let stop_requested = stopped.load(Ordering::Relaxed);
    print!("{}", report::summary_text(&report));
    if let Some(why) = &report.run.start_failure {
        anyhow::bail!("the pipeline did not start for the radar that connected: {why}");
    }
    if let Some(e) = report.driver_failure {
        return Err(anyhow::Error::new(e).context("the radar driver failed"));
    }
    // A recording of scans none of which reached the pipeline did not do the run's job.
    if let Some(r) = report
        .replay
        .as_ref()
        .filter(|_| report.run.summary.azimuths == 0 && !stop_requested)
    {
        anyhow::bail!(
            "{doing}: no azimuth of the recording reached the pipeline; {} of its {} scans skipped as damaged{}",
            r.scans_skipped,
            r.scans,
            r.first_scan_skipped
                .as_ref()
                .map_or(String::new(), |e| format!(", the first: {e}"))
        );
    }
    // A recording with no radar data the daemon could use did not do the run's job.
    if let Some(c) = report.mcap_replay.as_ref().filter(|c| c.azimuths == 0) {
        anyhow::bail!(
            "{doing}: the file held no radar data the daemon could replay{}",
            c.file_error
                .as_ref()
                .map_or(String::new(), |e| format!(" ({e})"))
        );
    }
    // A file cut short or corrupt was replayed up to the damage only: the summary above
    // says what was used; the status says the run did not get through the file.
    if let Some(e) = report
        .mcap_replay
        .as_ref()
        .and_then(|c| c.file_error.as_ref())
        .filter(|_| !stop_requested)
    {
        anyhow::bail!("{doing}: replayed up to where the file is damaged: {e}");
    }
    Ok(())
}

/// Ends the process as `why`'s signal does by default (SIGINT for Ctrl-C, SIGTERM), for a
/// stop before the run began: a shell sees 130 or 143 and stops a script there, since the run
/// made nothing to go on with; systemd counts a death by SIGTERM or SIGINT as a clean stop (the
/// unit ends inactive, not failed, as it would with status 1, and no `SuccessExitStatus=` is
/// needed, as it would be for `exit(143)`).
fn end_as_signalled(why: radar_driver::StopSignal) -> ! {
    let number = match why {
        radar_driver::StopSignal::CtrlC => 2,
        radar_driver::StopSignal::Term => 15,
    };
    #[cfg(unix)]
    {
        let signal = match why {
            radar_driver::StopSignal::CtrlC => signal_hook::consts::SIGINT,
            radar_driver::StopSignal::Term => signal_hook::consts::SIGTERM,
        };
        // The default action back in place, then the signal raised: the process ends here.
        let _ = signal_hook::low_level::emulate_default_handler(signal);
    }
    // Where the signal cannot be re-raised: the status a shell would show for it.
    std::process::exit(128 + number)
}

/// Prints every radar profile, each value with its source.
fn list_profiles() -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    for p in radar_model::profile::PROFILES
        .into_iter()
        .chain(radar_model::profile::SIMULATED)
    {
        // A closed pipe (`| head`) ends the listing, not the process with a panic.
        if writeln!(out, "{p}").is_err() {
            break;
        }
    }
    Ok(())
}
