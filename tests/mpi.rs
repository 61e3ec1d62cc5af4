//! `mpirun -n 1` and `mpirun -n 2 fdfsi run CASE` (the `petsc` feature: every rank runs the case,
//! the Newton systems are solved by PETSc on all of them together; a flow's systems are
//! assembled by rows, each rank its own) reproduce the serial run's quantities on
//! Schaefer-Turek 2D-1, the first steps of the cylinder at Re = 100, model problem 3, the first
//! steps of model problem 4 and the 3D Navier-Stokes problem of the scaling runs (with its
//! iterative solve and the velocity's block size), and a PETSc error ends every rank
//! (`cargo test --release --features petsc --test mpi`; needs the system's PETSc and Open MPI's
//! `mpirun`).
#![cfg(feature = "petsc")]

use fdfsi::case::{BoundaryType, Case, LinearMethod, MeshSpec, PetscMethod, SolidMeshSpec, WindkesselSpec};
use fdfsi::run::{run_case, RunOptions};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn cases_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("cases")
}

/// A fresh folder for this test process.
fn scratch(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("fdfsi-test-mpi-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// One `mpirun` at a time: each starts a process per rank, and this machine may have few cores.
static MPIRUN: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Runs `fdfsi run CASE --out DIR` on `ranks` MPI ranks; returns the parsed `summary.json` and the
/// log (stdout and stderr of all ranks).
fn mpirun(ranks: usize, case: &Path, out: &Path) -> (Value, String) {
    let _one = MPIRUN.lock().unwrap_or_else(|e| e.into_inner());
    let output = Command::new("mpirun")
        .args(["-n", &ranks.to_string(), "--oversubscribe"])
        .arg(env!("CARGO_BIN_EXE_fdfsi"))
        .args(["run", case.to_str().unwrap(), "--out", out.to_str().unwrap()])
        // Containers and CI often run as root, which mpirun refuses unless told.
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .output()
        .unwrap_or_else(|e| panic!("mpirun (Open MPI, which the petsc feature links) could not start: {e}"));
    let log = format!("{}{}", String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    assert!(output.status.success(), "mpirun -n {ranks} fdfsi run {}: {}\n{log}", case.display(), output.status);
    let summary = serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    (summary, log)
}

fn quantities(summary: &Value) -> BTreeMap<String, f64> {
    summary["quantities"].as_object().unwrap().iter().map(|(k, v)| (k.clone(), v.as_f64().unwrap())).collect()
}

/// The case `name` edited by `edit`, run serially (in this process, with the case's own linear
/// method) and by `mpirun -n 1` and `-n 2` with `method = "petsc"` and `solver`: the same
/// steps and quantities, to `tol` relative (plus `floor` absolute, for quantities that are zero
/// up to the solver tolerance) against the serial run and to 1e-9 between the two MPI runs.
fn compare(name: &str, solver: PetscMethod, tol: f64, floor: f64, edit: impl Fn(&mut Case)) -> String {
    compare_file(name, &cases_dir().join(format!("{name}.toml")), solver, tol, floor, edit)
}

/// [`compare`] for the case file `file`; returns the log of the run on 2 ranks.
fn compare_file(name: &str, file: &Path, solver: PetscMethod, tol: f64, floor: f64, edit: impl Fn(&mut Case)) -> String {
    let dir = scratch(&format!("{name}-{solver:?}"));
    let mut case = Case::read(file).unwrap();
    edit(&mut case);
    let serial = run_case(&case, &RunOptions::new(dir.join("serial"), cases_dir()), &mut |_: &str| {}).unwrap();
    case.solver.linear.method = LinearMethod::Petsc;
    case.solver.petsc.solver = solver;
    let file = dir.join("case.toml");
    std::fs::write(&file, case.to_toml()).unwrap();
    let (one, _) = mpirun(1, &file, &dir.join("n1"));
    let (two, log) = mpirun(2, &file, &dir.join("n2"));
    assert_eq!(two["ranks"], 2, "{name}: summary.json records the ranks");
    assert!(log.contains("done on 2 ranks"), "{name}: rank 0 logs\n{log}");
    assert_eq!(log.matches("case: ").count(), 1, "{name}: only rank 0 logs\n{log}");
    let close = |a: f64, b: f64, tol: f64| (a - b).abs() <= tol * a.abs().max(b.abs()) + floor;
    for (q, &s) in &serial.quantities {
        let (a, b) = (quantities(&one)[q], quantities(&two)[q]);
        println!("{name}: {q}: serial {s:.12e}, mpirun -n 1 {a:.12e}, -n 2 {b:.12e}");
        assert!(close(a, s, tol) && close(b, s, tol), "{name}: {q}: serial {s}, -n 1 {a}, -n 2 {b}");
        assert!(close(a, b, 1e-9), "{name}: {q}: -n 1 {a}, -n 2 {b}");
    }
    for summary in [&one, &two] {
        assert_eq!(summary["steps"], serial.steps, "{name}");
        assert_eq!(summary["dofs"]["total"], serial.dofs["total"], "{name}");
    }
    // Rank 0 wrote the results as a serial run does; the other rank's private folder is gone.
    for file in ["solution.pvd", "history.csv", "case.toml"] {
        assert!(dir.join("n2").join(file).exists(), "{name}: {file}");
    }
    assert!(!dir.join("n2/.rank1").exists(), "{name}: rank 1's private output folder was not removed");
    let _ = std::fs::remove_dir_all(&dir);
    log
}

/// Schaefer-Turek 2D-1 (steady Navier-Stokes) on the coarse mesh (36 596 unknowns), with MUMPS and
/// with the augmented Lagrangian through PETSc: drag, lift and pressure difference. The serial
/// run's Newton (inexact, its linear solves by the augmented-Lagrangian FGMRES) stops at
/// |R| <= 1e-10: the coefficients agree to 1e-9 absolute (measured 2.4e-10 for the lift, 2.3e-8
/// of its value of 1e-2; 2e-11 of the drag).
#[test]
fn schaefer_turek_2d1_on_two_ranks_gives_the_serial_quantities() {
    let mesh = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/dfg2d-coarse.msh");
    for solver in [PetscMethod::Mumps, PetscMethod::AugmentedLagrangian] {
        compare("schaefer-turek-2d1", solver, 1e-8, 1e-9, |c| c.mesh = Some(MeshSpec::Gmsh { file: mesh.clone() }));
    }
}

/// The Schaefer-Turek cylinder at Re = 100 (2D-2, unsteady Navier-Stokes, BDF2) on the coarse
/// mesh, its first 5 steps, with MUMPS through PETSc: a partitioned assembly in time (each
/// rank's rows of every step's Newton systems), the boundary forces from the whole residual on
/// every rank. Its Newton stops at |R| <= 1e-10: the drag and lift agree to 1e-9 absolute.
#[test]
fn the_cylinder_at_re_100_on_two_ranks_gives_the_serial_quantities() {
    let mesh = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/dfg2d-coarse.msh");
    compare("cylinder-re100", PetscMethod::Mumps, 1e-8, 1e-9, |c| {
        c.mesh = Some(MeshSpec::Gmsh { file: mesh.clone() });
        c.time.as_mut().unwrap().end = 0.05;
    });
}

/// An FSI run on 2 ranks logs a partitioned assembly with MUMPS, not with the augmented
/// Lagrangian (which takes the whole system).
fn assert_by_rows(log: &str, solver: PetscMethod) {
    let by_rows = log.contains("assembly: each rank its own rows of every step's system (this is rank 0 of 2)");
    assert_eq!(by_rows, matches!(solver, PetscMethod::Mumps), "{solver:?}: partitioned assembly\n{log}");
}

/// Model problem 3 (axisymmetric FSI, 60 steps), with MUMPS and with the augmented Lagrangian
/// through PETSc: the adapted mesh changes with the membrane, so
/// each rank adapts alike and the system's pattern is new from step to step. With MUMPS each
/// rank assembles its own rows of every step's system (the partition rebuilt every step); the
/// augmented Lagrangian takes the whole system. The equilibrium quantities that vanish
/// (downstream pressure, speed, flux: 1e-7 to 1e-8) agree to 1e-11 absolute.
#[test]
fn model_problem_3_on_two_ranks_gives_the_serial_quantities() {
    for solver in [PetscMethod::Mumps, PetscMethod::AugmentedLagrangian] {
        let log = compare("model-problem-3", solver, 1e-8, 1e-11, |_| {});
        assert_by_rows(&log, solver);
    }
}

/// Model problem 2 (2D FSI, 4 steps on a 32 x 8 mesh) with its outlet a Windkessel (issue 17):
/// the outlet's flux and capacitor pressure are unknowns of the system, in the rows of one rank,
/// coupled to velocity rows of both; by rows with MUMPS, the quantities (the outlet's pressure
/// among them) agree with the serial run's.
#[test]
fn a_windkessel_outlet_on_two_ranks_gives_the_serial_quantities() {
    let log = compare("model-problem-2", PetscMethod::Mumps, 1e-9, 1e-12, |c| {
        c.mesh = Some(MeshSpec::Rectangle { x: [0.0, 4.0], y: [0.0, 1.0], n: [32, 8] });
        c.time.as_mut().unwrap().end = 4.0;
        let outlet = c.boundary.iter_mut().find(|b| b.name == "right").unwrap();
        outlet.kind = BoundaryType::Windkessel;
        outlet.windkessel = Some(WindkesselSpec {
            proximal_resistance: 0.5,
            compliance: 0.2,
            distal_resistance: 2.0,
            distal_pressure: 0.0,
            initial_pressure: Some(0.4),
        });
    });
    assert_by_rows(&log, PetscMethod::Mumps);
}

/// Model problem 4 (3D FSI) on the coarser mesh of tests/cases.rs, 3 steps, with MUMPS and with
/// the augmented Lagrangian through PETSc (its 3D placements: the boundary groups and the
/// coupling multiplier in the Schur block, where FGMRES needs refined Gram-Schmidt and a
/// refinement of some solves; both failed the third step of the case's mesh); with MUMPS each
/// rank assembles its own rows. The case's Newton
/// stops at |R| <= 1e-9 (its serial linear solves: the augmented-Lagrangian FGMRES, inexact):
/// the forces on gamma_f (about 0.01-0.14) agree to 1e-8 absolute (measured 1.6e-9).
#[test]
fn model_problem_4_on_two_ranks_gives_the_serial_quantities() {
    for solver in [PetscMethod::Mumps, PetscMethod::AugmentedLagrangian] {
        let log = compare("model-problem-4", solver, 1e-8, 1e-8, |c| {
            c.mesh = Some(MeshSpec::Pipe { radius: 1.0, length: 4.0, n_radial: 4, n_axial: 6, quarter: true });
            let solid = c.solid.first_mut().unwrap();
            solid.mesh = SolidMeshSpec::QuarterDisc { radius: 1.0, z: [1.975, 2.025], n_core: 3, n_ring: 2, n_layers: 1 };
            c.time.as_mut().unwrap().end = 0.3;
        });
        assert_by_rows(&log, solver);
    }
}

/// The 3D Navier-Stokes problem of the scaling runs (`benches/scale3d`, plane Poiseuille flow at
/// Re = 100) on 8 x 4 x 2 box cells (7 623 unknowns), serially by fdfsi's augmented Lagrangian
/// and on 1 and 2 ranks by the benchmark's own PETSc options (FGMRES, a Schur field split,
/// BoomerAMG on the velocity, no LU): the serial run's quantities (the exact solution: centre
/// velocity 1.5, pressures 18 and 6, flux 0.5), and on 2 ranks PETSc's velocity block, the
/// field split's first field, of block size 3 (its view), so that BoomerAMG coarsens each
/// component apart; each rank assembles its own rows only (a partitioned assembly).
#[test]
fn the_scaling_problem_on_two_ranks_gives_the_serial_quantities() {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/scale3d/slab-3d-navier-stokes.toml");
    let log = compare_file("slab-3d-navier-stokes", &file, PetscMethod::Mumps, 1e-8, 1e-10, |c| {
        let Some(MeshSpec::Box { n, .. }) = c.mesh.as_mut() else { panic!("the scaling problem's mesh is a box") };
        *n = [8, 4, 2];
        c.solver.linear.method = LinearMethod::AugmentedLagrangian;
        c.solver.petsc.options.push_str(" -fdfsi_ksp_view");
    });
    let views = log.matches("Mat Object: (fdfsi_fieldsplit_primal_)").count();
    assert!(views > 0, "no view of the velocity block in the log\n{log}");
    let velocity_rows = 6_087;
    assert!(log.contains(&format!("rows={velocity_rows}, cols={velocity_rows}, bs=3")), "the velocity block's block size\n{log}");
    // Each rank assembled its own rows (a partitioned assembly), of 7 623 unknowns in all.
    assert!(log.contains("total 7623 (nnz") && log.contains("in rank 0's rows of 2)"), "rank 0 held its own rows\n{log}");
}

/// On several ranks a case must solve through PETSc: any other linear method would solve the
/// whole system on every rank. The run stops before it writes anything.
#[test]
fn several_ranks_need_the_petsc_method() {
    let dir = scratch("method");
    let out = dir.join("out");
    let output = Command::new("mpirun")
        .args(["-n", "2", "--oversubscribe", env!("CARGO_BIN_EXE_fdfsi"), "run"])
        .arg(cases_dir().join("channel-stokes.toml"))
        .arg("--out")
        .arg(&out)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success());
    assert!(log.contains("running on 2 MPI ranks: set `method = \"petsc\"`"), "{log}");
    assert!(!out.exists(), "nothing written");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A PETSc error on several ranks ends every rank at once, each printing the error with its rank:
/// an error that one rank met alone inside a collective call, returned, would send that rank on
/// (a Newton failure, a cut step, another collective call) while the others wait for it.
#[test]
fn a_petsc_error_on_two_ranks_ends_every_rank() {
    let dir = scratch("petsc-error");
    let mut case = Case::read(&cases_dir().join("channel-stokes.toml")).unwrap();
    case.solver.linear.method = LinearMethod::Petsc;
    case.solver.petsc.options = "-fdfsi_ksp_type no-such-method".into();
    let file = dir.join("case.toml");
    std::fs::write(&file, case.to_toml()).unwrap();
    let _one = MPIRUN.lock().unwrap_or_else(|e| e.into_inner());
    // A rank left waiting would hang the test: `timeout` fails it instead.
    let output = Command::new("timeout")
        .args(["300", "mpirun", "-n", "2", "--oversubscribe", env!("CARGO_BIN_EXE_fdfsi"), "run"])
        .arg(&file)
        .arg("--out")
        .arg(dir.join("out"))
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .output()
        .unwrap();
    let log = format!("{}{}", String::from_utf8_lossy(&output.stdout), String::from_utf8_lossy(&output.stderr));
    assert!(!output.status.success(), "{log}");
    assert_ne!(output.status.code(), Some(124), "the run did not end within 300 s\n{log}");
    assert!(log.contains("KSPSetFromOptions") && log.contains("ending every rank"), "{log}");
    assert!(!log.contains("done on 2 ranks"), "{log}");
    let _ = std::fs::remove_dir_all(&dir);
}
