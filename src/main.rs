//! `fdfsi`: the command line, a thin layer over the library.

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use fdfsi::case::builtin::{BUILTIN_CASES, DEFAULT_CASE, DEFAULT_CASE_NAME};
use fdfsi::case::Case;
use fdfsi::run::{check_case, run_case, RunObserver, RunOptions};
use fdfsi::verify::{self, Effort};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

#[derive(Parser)]
#[command(name = "fdfsi", version, about = "Fluid-structure interaction for heart-valve modelling (van Loon et al. 2005)")]
struct Cli {
    /// Print only errors.
    #[arg(long, short, global = true, conflicts_with = "verbose")]
    quiet: bool,
    /// Also print every Newton iteration and the phases of every step.
    #[arg(long, short, global = true)]
    verbose: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a case (a TOML file or a built-in case name; default: the built-in slab-one-beat case, an FSI run).
    ///
    /// Ctrl-C stops a time-dependent run after the current step and writes a checkpoint.
    Run {
        #[arg(conflicts_with = "resume")]
        case: Option<String>,
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Write a restart file (DIR/checkpoint.json) every N steps.
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
        checkpoint_every: Option<u64>,
        /// Continue the run whose output and checkpoint are in DIR (with the case stored there).
        #[arg(long, value_name = "DIR")]
        resume: Option<PathBuf>,
        /// Start from the state of the run whose checkpoint is in DIR (FSI cases) instead of
        /// from rest: at its time, on this case's fluid mesh, with this case's time step (which
        /// must divide that time) and outputs; the solid mesh must be the same.
        #[arg(long, value_name = "DIR", conflicts_with_all = ["resume", "export_system"])]
        start_from: Option<PathBuf>,
        /// Write the first Newton system (DIR/jacobian.mtx, rhs.mtx, blocks.json; augmented.mtx
        /// with the augmented-Lagrangian solver) instead of running (flow and FSI cases).
        #[arg(long, value_name = "DIR", conflicts_with = "resume")]
        export_system: Option<PathBuf>,
    },
    /// Parse and validate a case without running it; print a summary of the problem.
    Check { case: String },
    /// List the built-in cases, or print one (to start a case file from it).
    Cases { name: Option<String> },
    /// Adapt the case's fluid mesh to its solid (paper section 2.2.1) and write original.vtu,
    /// adapted.vtu, gamma_s.vtu, gamma_f.vtu and summary.json.
    Adapt {
        #[arg(required_unless_present = "at", conflicts_with = "at")]
        case: Option<String>,
        #[arg(long, default_value = "out-adapt")]
        out: PathBuf,
        /// Instead of a case: adapt an FSI run's fluid mesh to the solid of the checkpoint in
        /// RUN_DIR (the mesh its next step starts from; to inspect a step that failed).
        #[arg(long, value_name = "RUN_DIR")]
        at: Option<PathBuf>,
    },
    /// Draw PNG plots of a run's results into DIR/plots: every history.csv column against time,
    /// trajectories of STEM_x/STEM_y column pairs, and the profiles.
    Plot {
        dir: PathBuf,
        /// Draw the same quantities and profiles of these runs into the same plots.
        #[arg(long = "with", value_name = "OTHER_DIR")]
        with: Vec<PathBuf>,
    },
    /// Draw DIR/animation.gif of a time-dependent run: the speed at every output time of
    /// DIR/solution.pvd (3D: on the plane of speed.png), with the solid and gamma_f.
    Animate { dir: PathBuf },
    /// Run the manufactured-solution convergence studies and print errors and rates.
    Verify {
        /// Also write the studies as JSON.
        #[arg(long)]
        json: Option<PathBuf>,
        /// One more refinement level (slower).
        #[arg(long)]
        full: bool,
    },
}

/// A case from a file path or a built-in name, with the directory its relative paths refer to.
fn load_case(arg: Option<&str>) -> Result<(Case, PathBuf, String)> {
    let builtin_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    match arg {
        None => {
            let name = format!("{DEFAULT_CASE_NAME} (built-in)");
            Ok((Case::from_toml_str(DEFAULT_CASE, &name)?, builtin_dir, name))
        }
        Some(a) => {
            let path = Path::new(a);
            if path.exists() {
                let case = Case::read(path)?;
                let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
                Ok((case, dir, a.to_string()))
            } else if let Some((name, text)) = BUILTIN_CASES.iter().find(|(n, _)| *n == a) {
                let label = format!("{name} (built-in)");
                Ok((Case::from_toml_str(text, &label)?, builtin_dir, label))
            } else {
                let names: Vec<&str> = BUILTIN_CASES.iter().map(|(n, _)| *n).collect();
                bail!("no case file '{a}' and no built-in case of that name (built-in: {})", names.join(", "))
            }
        }
    }
}

/// Log lines on stderr; on a terminal, step progress as a bar (step, time, ETA) with the log
/// lines printed above it.
struct CliObserver {
    quiet: bool,
    verbose: bool,
    bar: Option<ProgressBar>,
    terminal: bool,
}

impl RunObserver for CliObserver {
    fn log(&mut self, line: &str) {
        if self.quiet {
            return;
        }
        match &self.bar {
            Some(bar) if line.starts_with("step ") => bar.set_message(line.to_string()),
            Some(bar) => bar.println(line),
            None => eprintln!("{line}"),
        }
    }
    fn detail(&mut self, line: &str) {
        if self.verbose {
            match &self.bar {
                Some(bar) => bar.println(line),
                None => eprintln!("{line}"),
            }
        }
    }
    fn step(&mut self, step: usize, total: usize, time: f64) {
        if self.quiet || !self.terminal {
            return;
        }
        let bar = self.bar.get_or_insert_with(|| {
            let b = ProgressBar::new(total as u64);
            b.set_style(
                ProgressStyle::with_template("{bar:30} {pos}/{len} steps, t = {prefix}, ETA {eta}  {wide_msg}")
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            b
        });
        bar.set_prefix(format!("{time:.4e}"));
        bar.set_position(step as u64);
        if step == total {
            bar.finish();
        }
    }
}

fn main() -> std::process::ExitCode {
    match run_command() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{}", error_report(&e));
            std::process::ExitCode::FAILURE
        }
    }
}

/// `Error: MESSAGE` and, under `Caused by:`, each cause whose text the message above it does not
/// already end with: the library's errors name their cause in their own message (`solid: {0}`), so
/// anyhow's report repeated every message once per level. No backtrace: these are errors of the
/// input or of the run, not of fdfsi (a panic still prints one with `RUST_BACKTRACE=1`).
fn error_report(e: &anyhow::Error) -> String {
    let mut report = format!("Error: {e}");
    let mut above = e.to_string();
    let mut causes = Vec::new();
    for cause in e.chain().skip(1) {
        let text = cause.to_string();
        if !above.ends_with(&text) {
            causes.push(text.clone());
        }
        above = text;
    }
    if !causes.is_empty() {
        report.push_str("\n\nCaused by:");
        for (i, c) in causes.iter().enumerate() {
            report.push_str(&format!("\n    {i}: {c}"));
        }
    }
    report
}

/// This process among the processes `mpirun` started (Open MPI's `OMPI_COMM_WORLD_SIZE` tells
/// it did): `fdfsi run` on several ranks solves each Newton system through PETSc on all of them
/// (`[solver.linear] method = "petsc"`, the `petsc` feature) and does everything else on every
/// rank alike (the meshes, the adaptation and the assembly are replicated); rank 0 writes the
/// results and the log, each other rank writes its copy into a private folder `OUT/.rankN`,
/// removed at the end. Ctrl-C stops a run mpirun started at once (mpirun ends every rank):
/// checkpoints (`--checkpoint-every`) are the way to resume it.
struct Ranks {
    rank: usize,
    size: usize,
    /// Started by mpirun: MPI is ended (or the run aborted on every rank) at the end.
    launched: bool,
}

impl Ranks {
    fn of_launch() -> Result<Ranks> {
        let Some(size) = std::env::var("OMPI_COMM_WORLD_SIZE").ok().and_then(|s| s.parse::<usize>().ok()) else {
            return Ok(Ranks { rank: 0, size: 1, launched: false });
        };
        #[cfg(feature = "petsc")]
        {
            let world = fdfsi::solve::petsc::world()?;
            if world.size != size {
                bail!("mpirun started {size} ranks, but MPI_COMM_WORLD has {}: is this fdfsi's MPI the one mpirun belongs to?", world.size);
            }
            Ok(Ranks { rank: world.rank, size: world.size, launched: true })
        }
        #[cfg(not(feature = "petsc"))]
        match size {
            1 => Ok(Ranks { rank: 0, size: 1, launched: false }),
            _ => bail!(
                "started by mpirun on {size} ranks, but this fdfsi was built without the `petsc` feature: every rank would run the whole case; build it with `cargo build --release --features petsc`"
            ),
        }
    }

    /// On several ranks the linear solves must be PETSc's (any other method would solve the
    /// whole system on every rank).
    fn check_method(&self, case: &Case) -> Result<()> {
        if self.size > 1 && case.solver.linear.method != fdfsi::case::LinearMethod::Petsc {
            bail!(
                "running on {} MPI ranks: set `method = \"petsc\"` in the case's [solver.linear] table (its method {} would solve the whole system on every rank)",
                self.size,
                serde_json::to_string(&case.solver.linear.method).unwrap_or_default()
            );
        }
        Ok(())
    }

    /// On a rank other than 0: points `options` at a private folder `OUT/.rankN` (with a copy
    /// of what a resumed run reads from the results folder) and returns it, to be removed at the
    /// end.
    fn private_out_dir(&self, options: &mut RunOptions) -> Result<Option<PathBuf>> {
        if self.rank == 0 {
            return Ok(None);
        }
        let dir = options.out_dir.join(format!(".rank{}", self.rank));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        if options.resume.is_some() {
            for name in ["checkpoint.json", "history.csv", "solution.pvd"] {
                let from = options.out_dir.join(name);
                if from.exists() {
                    std::fs::copy(&from, dir.join(name)).with_context(|| format!("copying {} to {}", from.display(), dir.display()))?;
                }
            }
        }
        options.out_dir = dir.clone();
        Ok(Some(dir))
    }

    /// `result`, or on several ranks its error printed (after the rank, but for rank 0) and
    /// every rank ended: a rank that failed alone would leave the others waiting for it.
    fn unless_failed<T>(&self, result: Result<T>) -> Result<T> {
        #[cfg(feature = "petsc")]
        if let (Err(e), true) = (&result, self.launched) {
            let rank = if self.rank > 0 { format!("rank {}: ", self.rank) } else { String::new() };
            eprintln!("{rank}{}", error_report(e));
            fdfsi::solve::petsc::abort(1);
        }
        result
    }

    /// Ends MPI after a run that mpirun started.
    fn finish(&self) {
        #[cfg(feature = "petsc")]
        if self.launched {
            fdfsi::solve::petsc::finalize();
        }
    }
}

/// What `fdfsi run` was asked (without `--export-system`).
struct RunRequest {
    case: Option<String>,
    out: PathBuf,
    checkpoint_every: Option<u64>,
    resume: Option<PathBuf>,
    start_from: Option<PathBuf>,
}

/// `fdfsi run`: on this rank of `ranks`, logging unless `quiet`.
fn run(request: RunRequest, ranks: &Ranks, quiet: bool, verbose: bool) -> Result<()> {
    let RunRequest { case, out, checkpoint_every, resume, start_from } = request;
    let log = |line: &str| {
        if !quiet {
            eprintln!("{line}");
        }
    };
    let (case, mut options, label) = match resume {
        Some(dir) => {
            let (case, options) = RunOptions::resume(&dir)?;
            let label = format!("{} (resumed)", dir.display());
            (case, options, label)
        }
        None => {
            let (case, case_dir, label) = load_case(case.as_deref())?;
            (case, RunOptions::new(out, case_dir), label)
        }
    };
    ranks.check_method(&case)?;
    options.ranks = ranks.size;
    options.checkpoint_every = checkpoint_every.map(|n| n as usize);
    options.start_from = start_from.map(fdfsi::run::StartFrom::read).transpose()?;
    if !ranks.launched {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        ctrlc::set_handler(move || {
            if flag.swap(true, Ordering::SeqCst) {
                std::process::exit(130); // a second Ctrl-C stops at once
            }
            eprintln!("\nstopping after this step (Ctrl-C again to stop now) ...");
        })
        .context("installing the Ctrl-C handler")?;
        options.stop = Some(stop);
    }
    log(&format!("case: {label}: {}", case.title));
    let results = options.out_dir.clone();
    let private = ranks.private_out_dir(&mut options)?;
    let mut observer = CliObserver { quiet, verbose, bar: None, terminal: std::io::stderr().is_terminal() };
    let result = run_case(&case, &options, &mut observer);
    if let Some(dir) = private {
        let _ = std::fs::remove_dir_all(dir);
    }
    let summary = match result {
        Err(e @ fdfsi::run::RunError::Interrupted { .. }) => {
            eprintln!("{e}");
            std::process::exit(130);
        }
        other => other.with_context(|| format!("running {label}"))?,
    };
    let t = &summary.timings;
    let memory = summary.peak_memory_mib.map(|m| format!(", peak memory {m:.0} MiB")).unwrap_or_default();
    let on = if ranks.size > 1 { format!(" on {} ranks", ranks.size) } else { String::new() };
    let failed = if t.failed_attempts > 0.0 { format!(", failed attempts {:.2} s", t.failed_attempts) } else { String::new() };
    log(&format!(
        "done{on} in {:.2} s (adapt {:.2} s, assemble {:.2} s, factorize {:.2} s, solve {:.2} s, output {:.2} s{failed}{memory}); results in {}",
        t.total,
        t.adapt,
        t.assemble,
        t.factorize,
        t.solve,
        t.output,
        results.display()
    ));
    Ok(())
}

fn run_command() -> Result<()> {
    let cli = Cli::parse();
    // Solver internals (the reuse of factorisations, their cost) log through `tracing`, off unless
    // FDFSI_LOG asks for them (e.g. FDFSI_LOG=debug).
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_env("FDFSI_LOG").unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("off")))
        .with_writer(std::io::stderr)
        .init();
    let (quiet, verbose) = (cli.quiet, cli.verbose);
    let log = |line: &str| {
        if !quiet {
            eprintln!("{line}");
        }
    };
    match cli.command {
        Command::Run { case, export_system: Some(dir), .. } => {
            let (case, case_dir, _) = load_case(case.as_deref())?;
            fdfsi::run::export::export_system(&case, &case_dir, &dir, &mut |line: &str| log(line))?;
        }
        Command::Run { case, out, checkpoint_every, resume, start_from, export_system: None } => {
            let ranks = Ranks::of_launch()?;
            let request = RunRequest { case, out, checkpoint_every, resume, start_from };
            ranks.unless_failed(run(request, &ranks, quiet || ranks.rank > 0, verbose && ranks.rank == 0))?;
            ranks.finish();
        }
        Command::Check { case } => {
            let (c, dir, label) = load_case(Some(&case))?;
            let text = check_case(&c, &label, &dir)?;
            println!("{label}: ok\n{text}");
        }
        Command::Adapt { case, out, at } => {
            let (label, s) = match at {
                Some(run_dir) => {
                    let label = format!("{} (checkpoint)", run_dir.display());
                    let s = fdfsi::run::adapt::adapt_checkpoint(&run_dir, &out).with_context(|| format!("adapting {label}"))?;
                    (label, s)
                }
                None => {
                    let (c, dir, label) = load_case(case.as_deref())?;
                    c.validate(&label)?;
                    let s = fdfsi::run::adapt::adapt_case(&c, &dir, &out).with_context(|| format!("adapting {label}"))?;
                    (label, s)
                }
            };
            let st = &s.stats;
            println!(
                "{label}: {} -> {} cells; {} cut edges, {} moved nodes, {} new nodes ({} moves refused), {} coupling facets",
                s.original_cells, s.adapted_cells, st.cut_edges, st.moved_nodes, st.new_nodes, st.refused_moves, st.coupling_facets
            );
            println!(
                "gamma_s: {} pieces, measure {:.6e}; gamma_f measure {:.6e}; min quality {:.3}; files in {}",
                s.gamma_s_pieces,
                s.gamma_s_measure,
                s.gamma_f_measure,
                st.min_quality,
                out.display()
            );
        }
        Command::Plot { dir, with } => {
            let files = fdfsi::io::plot::plot_compared(&dir, &with)?;
            for f in &files {
                println!("{}", f.display());
            }
            log(&format!("{} plots in {}", files.len(), dir.join("plots").display()));
        }
        Command::Animate { dir } => match fdfsi::io::animation::animate_run(&dir)? {
            Some(a) => {
                println!("{}", a.gif.display());
                log(&format!("{} frames in {}", a.frames, a.gif.display()));
                if let Some(solid) = a.solid_gif {
                    println!("{}", solid.display());
                    log(&format!("the solid seen along the flow: {}", solid.display()));
                }
            }
            None => anyhow::bail!("{}: nothing to animate (a run with fluid fields at two or more times is needed)", dir.display()),
        },
        Command::Cases { name } => match name {
            None => {
                for (n, text) in BUILTIN_CASES {
                    let title = Case::from_toml_str(text, n).map(|c| c.title).unwrap_or_default();
                    println!("{n:28} {title}");
                }
            }
            Some(n) => {
                let (_, text) = BUILTIN_CASES.iter().find(|(k, _)| *k == n).with_context(|| format!("no built-in case '{n}'"))?;
                print!("{text}");
            }
        },
        Command::Verify { json, full } => {
            let effort = if full { Effort::Full } else { Effort::Quick };
            let (report, runs) = verify::run_all(effort, |name| log(&format!("running {name} ...")))?;
            println!("{:28} {:16} {:>9} {:>9}   errors (h = mesh size or time step)", "study", "quantity", "expected", "observed");
            for s in &report.studies {
                let errs: Vec<String> = s.errors.iter().map(|e| format!("{e:.3e}")).collect();
                println!("{:28} {:16} {:>9.2} {:>9.3}   {}", s.name, s.quantity, s.expected_rate, s.observed_rate, errs.join(" "));
            }
            for c in &report.checks {
                println!(
                    "{:28} exact state reproduced: max |u - u_ex| = {:.2e}, max |p - p_ex| = {:.2e}",
                    c.name, c.displacement_error, c.pressure_error
                );
            }
            for r in &runs {
                println!("{}: max |int_K div u_h| = {:.2e}, dofs {:?}", r.studies[0].name, r.max_cell_divergence, r.dofs);
            }
            if let Some(path) = json {
                let text = serde_json::to_string_pretty(&report)?;
                fdfsi::io::write_atomic(&path, text.as_bytes())?;
                log(&format!("wrote {}", path.display()));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod report_tests {
    use super::error_report;
    use anyhow::Context;

    #[test]
    fn a_cause_the_message_above_it_ends_with_is_not_repeated() {
        let inner = std::io::Error::other("gamma_f does not enclose the solid");
        let quoted: anyhow::Result<()> = Err(inner).context("solid: gamma_f does not enclose the solid");
        let e = quoted.context("adapting b6.toml").unwrap_err();
        assert_eq!(error_report(&e), "Error: adapting b6.toml\n\nCaused by:\n    0: solid: gamma_f does not enclose the solid");
        let plain = anyhow::anyhow!("line 1: key with no value");
        assert_eq!(error_report(&plain), "Error: line 1: key with no value");
    }
}
