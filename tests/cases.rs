//! Every case in `cases/` runs and reproduces its documented check (see each file's header).

use fdfsi::case::builtin::BUILTIN_CASES;
use fdfsi::case::Case;
use fdfsi::fem::vtk::{read_pvd, read_vtu};
use fdfsi::io::checkpoint::Checkpoint;
use fdfsi::run::{run_case, RunOptions, RunSummary};
use std::path::{Path, PathBuf};

fn run(name: &str) -> (RunSummary, PathBuf) {
    run_with(name, |_| {})
}

/// Runs a case after `edit` changed it (e.g. a shorter end time).
fn run_with(name: &str, edit: impl FnOnce(&mut Case)) -> (RunSummary, PathBuf) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let file = dir.join(format!("{name}.toml"));
    let mut case = Case::read(&file).unwrap();
    edit(&mut case);
    // A folder per call: tests running the same case at once must not share one.
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let out = std::env::temp_dir().join(format!("fdfsi-test-{name}-{}-{call}", std::process::id()));
    let summary = run_case(&case, &RunOptions::new(out.clone(), dir), &mut |_: &str| {}).unwrap();
    (summary, out)
}

/// `out/summary.json`, parsed.
fn summary_json(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
}

/// The provenance in `out/summary.json`, checked to name the run's `case.toml` by its hash.
fn provenance(out: &Path) -> fdfsi::io::provenance::Provenance {
    let p: fdfsi::io::provenance::Provenance = serde_json::from_value(summary_json(out)["provenance"].clone())
        .unwrap_or_else(|e| panic!("{}: summary.json has no provenance ({e}): made before 2ad5061; move it away to run again", out.display()));
    let case_text = std::fs::read_to_string(out.join("case.toml")).unwrap();
    assert_eq!(p.case_sha256, fdfsi::io::provenance::sha256_hex(case_text.as_bytes()), "{}: case.toml changed after the run", out.display());
    p
}

/// `summary.json` records the code and the case that made the run (every kind of run: flow in
/// `channel_stokes_is_poiseuille_mid_channel`, solid, FSI).
fn assert_has_provenance(out: &Path) {
    assert_eq!(provenance(out).build, fdfsi::io::provenance::Build::current());
}

fn q(s: &RunSummary, name: &str) -> f64 {
    *s.quantities.get(name).unwrap_or_else(|| panic!("quantity {name} missing"))
}

/// Asserts each `(quantity, reference, limit)`: the quantity within `limit` of the reference,
/// relative to it.
fn assert_near_references(s: &RunSummary, references: &[(&str, f64, f64)]) {
    for &(name, value, limit) in references {
        let e = (q(s, name) - value).abs() / value.abs();
        println!("{name} = {:.5e} (reference {value:.5e}, {e:.2e})", q(s, name));
        assert!(e < limit, "{name}: {} against {value}", q(s, name));
    }
}

#[test]
fn every_case_file_is_a_builtin_and_is_tested() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    // The case files (beside them: the data they read, e.g. a waveform table).
    let case_file = |p: std::path::PathBuf| p.extension().is_some_and(|e| e == "toml").then(|| p.file_stem()?.to_str().map(String::from)).flatten();
    let mut files: Vec<String> = std::fs::read_dir(&dir).unwrap().filter_map(|e| case_file(e.ok()?.path())).collect();
    files.sort();
    let mut builtin: Vec<String> = BUILTIN_CASES.iter().map(|(n, _)| n.to_string()).collect();
    builtin.sort();
    assert_eq!(files, builtin, "cases/ and BUILTIN_CASES must list the same cases");
    let this = include_str!("cases.rs");
    for name in &files {
        assert!(this.contains(&format!("(\"{name}\"")), "case {name} has no test here");
    }
}

#[test]
fn lid_driven_cavity_at_re_1000_converges_from_rest_to_the_benchmark() {
    let (s, _) = run("lid-driven-cavity-re1000");
    // Botella & Peyret 1998 (independent: spectral collocation), at their extrema's locations.
    for (name, reference) in [("u_centreline_min", -0.3885698), ("v_centreline_max", 0.3769447), ("v_centreline_min", -0.5270771)] {
        let v = q(&s, name);
        println!("cavity Re 1000: {name} = {v:.8} (Botella & Peyret {reference}, error {:.1e})", (v / reference - 1.0).abs());
        assert!((v / reference - 1.0).abs() < 1e-3, "{name} = {v}, reference {reference}");
    }
    assert!(*s.residual_norms.last().unwrap() < 1e-10);
}

#[test]
fn channel_stokes_is_poiseuille_mid_channel() {
    let (s, out) = run("channel-stokes");
    // Plane Poiseuille lies in P2: exact mid-channel (the zero-pressure outlet disturbs the
    // flow only within about one channel height of the outlet).
    assert!((q(&s, "centre_velocity") - 1.5).abs() < 1e-9, "{}", q(&s, "centre_velocity"));
    // dp/dx = -12 eta U / H^2 = -12.
    let dp = q(&s, "pressure_at_x9") - q(&s, "centre_pressure");
    assert!((dp - 12.0).abs() < 1e-8, "pressure drop per unit length {dp}");
    // Mass conservation to round-off.
    assert!((q(&s, "inlet_flux") + 1.0).abs() < 1e-12);
    assert!((q(&s, "inlet_flux") + q(&s, "outlet_flux")).abs() < 1e-12);
    // A steady run has its picture, and nothing to animate.
    assert!(out.join("speed.png").exists() && !out.join("animation.gif").exists());
    assert!(matches!(fdfsi::io::animation::animate_run(&out), Ok(None)));
    // The default augmented-Lagrangian solver: one split of the system, one analysis of its LU.
    assert_eq!(s.symbolic_factorizations, 2);
    // The written solution reads back: P2 nodes carry the Poiseuille profile.
    let entries = read_pvd(&out.join("solution.pvd")).unwrap();
    assert_eq!(entries.len(), 1);
    assert_eq!(entries[0].name, "fluid");
    let grid = read_vtu(&entries[0].resolve(&out.join("solution.pvd"))).unwrap();
    let vel = grid.point_array("velocity").unwrap();
    let mut checked = 0;
    for (i, p) in grid.points.iter().enumerate() {
        if (p[0] - 10.0).abs() < 3.0 {
            let exact = 6.0 * p[1] * (1.0 - p[1]);
            assert!((vel.values[3 * i] - exact).abs() < 1e-9, "u at {p:?}");
            assert!(vel.values[3 * i + 1].abs() < 1e-9);
            checked += 1;
        }
    }
    assert!(checked > 20);
    assert_eq!(grid.cell_array("pressure").unwrap().values.len(), s.cells);
    let history = std::fs::read_to_string(out.join("history.csv")).unwrap();
    assert!(history.starts_with("step,time,newton_iterations,residual,"));
    let summary = summary_json(&out);
    assert!(summary["quantities"]["centre_velocity"].as_f64().is_some());
    if cfg!(target_os = "linux") {
        let mib = summary["peak_memory_mib"].as_f64().expect("peak memory on Linux");
        assert!(mib > 1.0 && mib < 1e6, "peak memory {mib} MiB");
    }
    assert!(out.join("case.toml").exists());
    // Provenance: the code (version, commit, modified, profile) and the case that made the run.
    let p = &summary["provenance"];
    assert_eq!(p["fdfsi_version"].as_str(), Some(env!("CARGO_PKG_VERSION")));
    let commit = p["git_commit"].as_str().expect("git_commit");
    assert!(commit == "unknown" || (commit.len() == 40 && commit.chars().all(|c| c.is_ascii_hexdigit())), "{commit}");
    assert!(p["git_modified"].is_boolean() && p["earlier_parts"].as_array().is_some_and(Vec::is_empty), "{p}");
    assert_eq!(p["build_profile"].as_str(), Some(if cfg!(debug_assertions) { "debug" } else { "release" }));
    assert_has_provenance(&out);
    // Wall shear stress on the bottom wall: eta du/dy = 6 eta U / H = 6 in the fully developed
    // part, pointing downstream (+x, the direction of increasing s on the bottom wall).
    let wss = std::fs::read_to_string(out.join("profiles/wss_bottom.csv")).unwrap();
    let mut lines = wss.lines();
    assert_eq!(lines.next(), Some("s,x,y,value"));
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    assert!(rows.windows(2).all(|w| w[1][0] > w[0][0]), "s increases");
    let mid: Vec<&Vec<f64>> = rows.iter().filter(|r| (r[1] - 10.0).abs() < 3.0).collect();
    assert!(mid.len() > 10);
    for r in mid {
        assert!((r[3] - 6.0).abs() < 1e-8, "wss at x = {}: {}", r[1], r[3]);
    }
}

/// SUPG is consistent on a whole case: the channel at Reynolds number 100 (viscosity 0.01, cell
/// Reynolds number up to 26), Navier-Stokes with `stabilization = "supg"`, is still plane
/// Poiseuille flow mid-channel, to 1e-9, with its pressure drop `12 eta U / H^2` per length: the
/// strong residual, second derivatives included, is zero there, so the stabilisation adds
/// nothing.
#[test]
fn channel_navier_stokes_with_supg_is_still_poiseuille() {
    use fdfsi::case::FlowModel;
    use fdfsi::physics::fluid::Stabilization;
    let (s, _) = run_with("channel-stokes", |c| {
        c.physics.model = FlowModel::NavierStokes;
        let fluid = c.fluid.as_mut().unwrap();
        fluid.viscosity = 0.01;
        fluid.stabilization = Stabilization::Supg;
    });
    println!("centre velocity {:.12}, pressure drop {:.12}", q(&s, "centre_velocity"), q(&s, "pressure_at_x9") - q(&s, "centre_pressure"));
    assert!((q(&s, "centre_velocity") - 1.5).abs() < 1e-9, "{}", q(&s, "centre_velocity"));
    let dp = q(&s, "pressure_at_x9") - q(&s, "centre_pressure");
    assert!((dp - 0.12).abs() < 1e-9, "pressure drop per unit length {dp}");
}

#[test]
fn axisymmetric_pipe_is_hagen_poiseuille_to_round_off() {
    let (s, _) = run("pipe-axisymmetric-stokes");
    assert!((q(&s, "axis_velocity") - 2.0).abs() < 1e-10, "{}", q(&s, "axis_velocity"));
    assert!((q(&s, "inlet_flux") + std::f64::consts::PI).abs() < 1e-11);
    assert!((q(&s, "outlet_flux") - std::f64::consts::PI).abs() < 1e-11);
    let dp = q(&s, "pressure_at_z2") - q(&s, "pressure_at_z3");
    assert!((dp - 8.0).abs() < 1e-9, "{dp}");
    // The largest speed is the axis velocity, sampled at vertices on the axis.
    assert!((q(&s, "max_speed") - 2.0).abs() < 1e-10, "{}", q(&s, "max_speed"));
    // Over r >= 0.5 only: the speed at r = 0.5, 2 (1 - 0.25).
    assert!((q(&s, "max_speed_outer_half") - 1.5).abs() < 1e-10, "{}", q(&s, "max_speed_outer_half"));
}

#[test]
fn quarter_pipe_3d_conserves_mass() {
    let (s, out) = run("quarter-pipe-3d-stokes");
    let (qin, qout) = (q(&s, "inlet_flux"), q(&s, "outlet_flux"));
    assert!((qin + qout).abs() < 1e-11 * qin.abs(), "{qin} vs {qout}");
    assert!(out.join("speed.png").exists(), "the speed on the plane through the middle of the pipe");
    // Coarse polygonal pipe: the axis velocity is near 2 (within 5 %).
    assert!((q(&s, "axis_velocity") - 2.0).abs() < 0.1, "{}", q(&s, "axis_velocity"));
}

#[test]
fn cylinder_on_curved_gmsh_mesh_conserves_mass() {
    let (s, _) = run("cylinder-stokes-gmsh");
    assert!((q(&s, "inlet_flux") + 0.082).abs() < 1e-12);
    assert!((q(&s, "inlet_flux") + q(&s, "outlet_flux")).abs() < 1e-12);
}

#[test]
fn schaefer_turek_2d1_matches_the_benchmark() {
    let (s, _) = run("schaefer-turek-2d1");
    // Independent references (John & Matthies 2001, the digits the case header cites). README:
    // drag error 1.2e-5, lift 0.12 %, pressure difference 0.29 %; held at 3e-5, 0.5 %, 0.5 %.
    const DRAG: f64 = 5.57953523384;
    let rel = |s: &RunSummary, name: &str, reference: f64| (q(s, name) - reference).abs() / reference.abs();
    println!(
        "2D-1 medium: {} dofs, drag {:.7} ({:.2e}), lift {:.7} ({:.2e}), dp {:.6} ({:.2e})",
        s.dofs["total"],
        q(&s, "drag_coefficient"),
        rel(&s, "drag_coefficient", DRAG),
        q(&s, "lift_coefficient"),
        rel(&s, "lift_coefficient", 0.010618948146),
        q(&s, "pressure_difference"),
        rel(&s, "pressure_difference", 0.11752016697)
    );
    assert_eq!(s.dofs["total"], 144_788, "the medium mesh's dofs (README)");
    assert!(rel(&s, "drag_coefficient", DRAG) < 3e-5, "drag {}", q(&s, "drag_coefficient"));
    assert!(rel(&s, "lift_coefficient", 0.010618948146) < 5e-3, "lift {}", q(&s, "lift_coefficient"));
    assert!(rel(&s, "pressure_difference", 0.11752016697) < 5e-3, "dp {}", q(&s, "pressure_difference"));
    // Regression values (fdfsi at 2ad5061), to catch drift below the benchmark's precision.
    for (name, value) in [("drag_coefficient", 5.579470), ("lift_coefficient", 0.0106317), ("pressure_difference", 0.117865)] {
        assert!((q(&s, name) - value).abs() < 1e-6 * value.abs().max(1.0), "{name} {} moved from {value}", q(&s, name));
    }
    // The coarse mesh (36 596 dofs; drag error 9.1e-5) is less accurate: the drag tolerance above
    // tells it apart.
    let (coarse, _) = run_with("schaefer-turek-2d1", |c| c.mesh = Some(fdfsi::case::MeshSpec::Gmsh { file: "../meshes/dfg2d-coarse.msh".into() }));
    let coarse_drag = rel(&coarse, "drag_coefficient", DRAG);
    println!(
        "2D-1 coarse: {} dofs, drag {:.7} ({coarse_drag:.2e}), lift {:.7} ({:.2e}), dp {:.6} ({:.2e})",
        coarse.dofs["total"],
        q(&coarse, "drag_coefficient"),
        q(&coarse, "lift_coefficient"),
        rel(&coarse, "lift_coefficient", 0.010618948146),
        q(&coarse, "pressure_difference"),
        rel(&coarse, "pressure_difference", 0.11752016697)
    );
    assert!(coarse_drag > 3e-5, "{coarse_drag}");
    assert_eq!(coarse.dofs["total"], 36_596);
    // Regression values of the coarse mesh (cases/schaefer-turek-2d1.toml; fdfsi at 2ad5061).
    for (name, value) in [("drag_coefficient", 5.579026), ("lift_coefficient", 0.0104019), ("pressure_difference", 0.118061)] {
        assert!((q(&coarse, name) - value).abs() < 1e-6, "coarse {name} {} moved from {value}", q(&coarse, name));
    }
    // Newton converges quadratically: the last residual drops far below the square of the one
    // before it times a modest constant.
    let r = &s.residual_norms;
    assert!(r.len() >= 3 && r.len() <= 8, "{r:?}");
    let (a, b) = (r[r.len() - 3], r[r.len() - 2]);
    assert!(b < 1e-2 * a, "{r:?}");
    assert_eq!(s.symbolic_factorizations, 2, "one split and one LU analysis per mesh");
}

#[test]
fn womersley_matches_the_bessel_solution_over_a_period() {
    use fdfsi::verify::womersley::Womersley;
    let (s, out) = run("womersley-axisymmetric");
    assert_eq!(s.steps, 1000);
    let w = Womersley { a: 1.0, rho: 1.0, nu: 1.0, omega: 25.0, radius: 1.0 };
    let period = 2.0 * std::f64::consts::PI / 25.0;
    let scale = w.amplitude(0.0).norm();
    let text = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (ct, c0, c5, c8) = (col("time"), col("u_r0"), col("u_r05"), col("u_r08"));
    let mut worst: f64 = 0.0;
    let mut rows = 0;
    for line in lines {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        let t = v[ct];
        if t < 4.0 * period - 1e-9 {
            continue;
        }
        rows += 1;
        for (c, r) in [(c0, 0.0), (c5, 0.5), (c8, 0.8)] {
            worst = worst.max((v[c] - w.velocity(r, t)).abs() / scale);
        }
    }
    assert!(rows >= 200, "{rows} rows in the last period");
    println!("Womersley: max error over the last period / centreline amplitude = {worst:.3e}");
    // Independent reference: the Bessel solution. README: 0.11 % (measured 1.108e-3).
    assert!(worst < 2e-3, "{worst}");
}

#[test]
fn skewed_plate_dirichlet_twin_adapts_and_conserves_mass() {
    let (s, run_out) = run("skewed-plate-dirichlet");
    // Shear-stress profiles on both faces, with the same points (the two sides of gamma_f).
    let read = |name: &str| -> Vec<Vec<f64>> {
        let text = std::fs::read_to_string(run_out.join(format!("profiles/{name}.csv"))).unwrap();
        text.lines().skip(1).map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect()
    };
    let (up, down) = (read("wss_upstream_side"), read("wss_downstream_side"));
    assert_eq!(up.len(), down.len());
    assert!(up.len() >= 10 && up.iter().chain(&down).all(|r| r[3].is_finite()));
    let length = up.last().unwrap()[0] - up[0][0];
    assert!(length > 0.3 && length < 0.4, "{length}");
    assert!((q(&s, "inlet_flux") + 1.0).abs() < 1e-12);
    assert!((q(&s, "inlet_flux") + q(&s, "outlet_flux")).abs() < 1e-12);
    // The flow pushes the plate downstream.
    assert!(q(&s, "plate_force_x") > 0.0);
    // `fdfsi adapt` on the same case: gamma_f lies on gamma_s and covers it except near its free
    // ends (the paper's algorithm puts no node at an end of gamma_s inside the fluid).
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let case = Case::read(&dir.join("skewed-plate-dirichlet.toml")).unwrap();
    let out = std::env::temp_dir().join(format!("fdfsi-test-adapt-{}", std::process::id()));
    let a = fdfsi::run::adapt::adapt_case(&case, &dir, &out).unwrap();
    assert!(a.gamma_f_measure <= a.gamma_s_measure * (1.0 + 1e-12));
    assert!(a.gamma_f_measure > 0.8 * a.gamma_s_measure, "{a:?}");
    assert_eq!(a.stats.coupling_facets, read_vtu(&out.join("gamma_f.vtu")).unwrap().num_cells());
    assert_eq!(a.adapted_cells, read_vtu(&out.join("adapted.vtu")).unwrap().num_cells());
    assert_eq!(read_vtu(&out.join("gamma_s.vtu")).unwrap().num_cells(), a.gamma_s_pieces);
    assert!(a.stats.min_quality > 0.0);
}

#[test]
fn cylinder_re100_starts_up_cleanly() {
    // The full run (t = 8, 800 steps) takes about 15 minutes: the ignored test
    // cylinder_re100_sheds_at_the_benchmark_strouhal_number below, and BENCHMARKS.md;
    // here: the first five steps of the ramped start-up.
    let (s, out) = run_with("cylinder-re100", |c| c.time.as_mut().unwrap().end = 0.05);
    assert_eq!(s.steps, 5);
    // Ramped inflow: after 0.05 s the flow carries 5 % of the full rate; drag positive, lift
    // near zero (the wake is still symmetric).
    assert!(q(&s, "drag_coefficient") > 0.0);
    assert!(q(&s, "lift_coefficient").abs() < 1e-2 * q(&s, "drag_coefficient"));
    let history = std::fs::read_to_string(out.join("history.csv")).unwrap();
    assert_eq!(history.lines().count(), 1 + 1 + 5, "header, the initial state and 5 steps");
    let pvd = read_pvd(&out.join("solution.pvd")).unwrap();
    assert_eq!(pvd.len(), 2, "initial state and the last step (output_every = 50)");
}

#[test]
fn cook_membrane_tip_displacement_is_the_regression_value() {
    let (s, out) = run("cook-membrane");
    // Regression value (fdfsi at 2ad5061): 6.889 mm on 8 x 8 cells. No published converged value
    // for these parameters was found (EXACT-SOLUTIONS.md 1.6); the convergence on 2-16 cells per
    // side and the locking of displacement-only Q2 are tests/solid_stepping.rs.
    let tip = q(&s, "tip_displacement_y");
    assert!((tip - 6.889).abs() < 5e-4, "{tip}");
    assert_has_provenance(&out);
    let entries = read_pvd(&out.join("solution.pvd")).unwrap();
    assert_eq!(entries[0].name, "solid");
    let grid = read_vtu(&entries[0].resolve(&out.join("solution.pvd"))).unwrap();
    assert_eq!(grid.cell_array("cauchy_stress").unwrap().values.len(), 9 * s.cells);
    assert!(grid.point_array("displacement").is_some());
}

/// Turek-Hron CFD1 (Re = 20) and CFD2 (Re = 100), steady flow around the rigid cylinder and bar:
/// drag within 0.5 % and lift within 2 % of Turek & Hron's (independent reference; the issue's
/// tolerances; measured 0.09 % / 0.77 % and 0.015 % / 0.17 %), from rest with the defaults.
#[test]
fn turek_hron_cfd1_and_cfd2_forces_match_the_benchmark() {
    for (name, drag, lift) in [("turek-hron-cfd1", 14.29, 1.119), ("turek-hron-cfd2", 136.7, 10.53)] {
        let (s, _) = run(name);
        let (ed, el) = ((q(&s, "drag") - drag).abs() / drag, (q(&s, "lift") - lift).abs() / lift);
        println!("{name}: drag {:.6} ({ed:.2e}), lift {:.6} ({el:.2e}), {} dofs", q(&s, "drag"), q(&s, "lift"), s.dofs["total"]);
        assert!(ed < 5e-3 && el < 2e-2, "{name}: drag error {ed:.2e}, lift error {el:.2e}");
    }
}

/// Turek-Hron CFD3's first 0.05 s (CI): the inflow starts from rest (a quarter sine over 2 s), the
/// drag on the obstacle grows from step to step, and the lift stays small beside it (the wake is
/// still symmetric).
#[test]
fn turek_hron_cfd3_starts_from_rest() {
    let (s, out) = run_with("turek-hron-cfd3", |c| c.time.as_mut().unwrap().end = 0.05);
    assert_eq!(s.steps, 10);
    let h = history_columns(&out);
    let (drag, lift) = (&h["drag"], &h["lift"]);
    assert!(drag[1..].windows(2).all(|w| w[1] > w[0] && w[0] > 0.0), "{drag:?}");
    assert!(lift.iter().zip(drag).all(|(l, d)| l.abs() < 0.05 * d.abs().max(1e-12)), "{lift:?} against {drag:?}");
}

/// The whole of Turek-Hron CFD3 (10 s, 2 000 BDF2 steps on the 128 048-dof mesh; about 70 min):
/// drag mean and amplitude, lift amplitude and frequency over the last period within 3 % of
/// Turek & Hron's (independent reference; the tolerance; measured at most 0.49 %), the
/// lift's mean within 10 % (measured 7.3 %: not yet the 3 %).
#[test]
#[ignore = "about 70 minutes; run with --ignored"]
fn turek_hron_cfd3_sheds_at_the_benchmark_forces_and_frequency() {
    let (s, _) = run("turek-hron-cfd3");
    assert_near_references(
        &s,
        &[
            ("drag_mean", 439.45, 3e-2),
            ("drag_amplitude", 5.6183, 3e-2),
            ("lift_mean", -11.893, 0.1),
            ("lift_amplitude", 437.81, 3e-2),
            ("lift_frequency", 4.3956, 3e-2),
        ],
    );
}

/// Turek & Hron's FSI1 (table 8, finest level): ux(A), uy(A) in m, drag, lift in N/m.
const FSI1: [(&str, f64); 4] = [("ux_A", 2.27e-5), ("uy_A", 8.209e-4), ("drag", 14.295), ("lift", 0.7638)];

/// Turek-Hron FSI1 on the coarser fluid mesh (turek-hron-fsi-fitted-0.msh, 44 207 dofs, 12 steps
/// of 5 s to the steady state; about 10 s): ux and lift within 3 % of Turek & Hron's (independent
/// reference; the tolerance; measured 0.04 %, 0.94 %), the drag within 1 % and uy within
/// 5 % (measured 0.78 % low and 4.1 % high on this coarse level: not the 0.5 % and 3 %;
/// the shipped level 2 has 0.26 % and 1.3 %). The bar's force from the fluid's stress on gamma_f
/// agrees with the multiplier's to 1 %.
#[test]
fn turek_hron_fsi1_on_the_coarse_mesh() {
    let (s, out) = run_with("turek-hron-fsi1", |c| {
        if let Some(fdfsi::case::MeshSpec::Gmsh { file }) = c.mesh.as_mut() {
            *file = file.to_string_lossy().replace("turek-hron-fsi-2", "turek-hron-fsi-fitted-0").into();
        }
    });
    assert_has_provenance(&out);
    assert!(q(&s, "coupling_facets") < 100.0, "the coarse mesh was used: {} coupling facets", q(&s, "coupling_facets"));
    assert_near_references(&s, &[("ux_A", FSI1[0].1, 3e-2), ("uy_A", FSI1[1].1, 5e-2), ("drag", FSI1[2].1, 1e-2), ("lift", FSI1[3].1, 3e-2)]);
    for (a, b) in [("drag", "drag_fluid_side"), ("lift", "lift_fluid_side")] {
        assert!((q(&s, a) - q(&s, b)).abs() < 1e-2 * q(&s, a).abs(), "{a} {} against {b} {}", q(&s, a), q(&s, b));
    }
}

/// Turek-Hron FSI1 as shipped (turek-hron-fsi-2.msh, 660 593 dofs; about 9 minutes and 11.4 GiB):
/// drag within 0.5 %, ux, uy and lift within 3 % of Turek & Hron's (the tolerances;
/// measured 0.26 %, 0.06 %, 1.33 %, 0.32 %; BENCHMARKS.md "Turek-Hron FSI1").
#[test]
#[ignore = "about 9 minutes and 11 GiB; run with --ignored"]
fn turek_hron_fsi1_matches_the_benchmark() {
    let (s, _) = run("turek-hron-fsi1");
    assert_near_references(&s, &[("ux_A", FSI1[0].1, 3e-2), ("uy_A", FSI1[1].1, 3e-2), ("drag", FSI1[2].1, 5e-3), ("lift", FSI1[3].1, 3e-2)]);
}

/// Turek-Hron FSI2 and FSI3, their first 10 steps (CI): the flow starts from rest under the
/// ramped inflow; every BDF2 step converges in at most 4 Newton iterations, the drag grows from
/// step to step, and gamma_f keeps the bar's three sides (114 facets on turek-hron-fsi-0.msh).
#[test]
fn turek_hron_fsi2_and_fsi3_start_from_rest() {
    for name in ["turek-hron-fsi2", "turek-hron-fsi3"] {
        let (s, out) = run_with(name, |c| {
            let t = c.time.as_mut().unwrap();
            t.end = 10.0 * t.dt;
        });
        assert_has_provenance(&out);
        let h = history_columns(&out);
        assert_eq!(h["time"].len(), 10, "{name}");
        assert!(h["newton_iterations"].iter().all(|&n| (1.0..=4.0).contains(&n)), "{name}: {:?}", h["newton_iterations"]);
        assert!(h["drag"].windows(2).all(|w| w[1] > w[0]), "{name}: drag {:?}", h["drag"]);
        assert!(h["coupling_facets"].iter().all(|&n| n == 114.0), "{name}: {:?}", h["coupling_facets"]);
        println!("{name}: drag {:.4e} after 10 steps, uy(A) {:.3e}", q(&s, "drag"), q(&s, "uy_A"));
    }
}

/// Turek & Hron's FSI2 and FSI3 (tables 10 and 12, finest level): uy(A)'s mean, amplitude (m)
/// and frequency, the drag's mean (N/m).
const FSI2_3: [(&str, [f64; 4]); 2] = [("turek-hron-fsi2", [1.23e-3, 80.6e-3, 2.0, 208.83]), ("turek-hron-fsi3", [1.48e-3, 34.38e-3, 5.3, 457.3])];

/// The whole of Turek-Hron FSI2 and FSI3 (about 4 hours each here): uy(A)'s amplitude within 5 %
/// and frequency within 3 % of Turek & Hron's, the mean drag within 2 % (the issue's
/// tolerances). NOT MET yet by the shipped cases on `turek-hron-fsi-0.msh` (sessions 16-17): FSI3's
/// amplitude is 6.8 % low and its frequency 3.1 % above 5.3 Hz, FSI2's frequency 3.1 % low and its
/// mean drag 2.3 % low (BENCHMARKS.md "Turek-Hron FSI2 and FSI3"); this test fails until the
/// cases reach the tolerances, and is kept at them as the target. On the second mesh
/// level (session 18, runs started from the level-0 states) the amplitudes and mean drags meet
/// them; the uy frequencies are 3.4 % (FSI3) and 3.3 % (FSI2) from 5.3 and 2.0 Hz, and 0.6 % and
/// 1.8 % from 5.45 and 1.9 Hz, half the reference's ux frequencies: which to hold is open.
#[test]
#[ignore = "about 8 hours, and fails on the shipped level-0 meshes (see its doc); run with --ignored"]
fn turek_hron_fsi2_and_fsi3_swing_at_the_benchmark_amplitudes_and_frequencies() {
    for (name, [_, amplitude, frequency, drag]) in FSI2_3 {
        let (s, _) = run(name);
        println!("{name}:");
        assert_near_references(&s, &[("uy_A_amplitude", amplitude, 5e-2), ("uy_A_frequency", frequency, 3e-2), ("drag_mean", drag, 2e-2)]);
    }
}

/// Turek-Hron CSM1 and CSM2 (the static bar under gravity): the displacement of A within 1 % of
/// Turek & Hron's (independent reference; the tolerance) on the shipped 40 x 4 mesh
/// (measured at most 0.44 %), and within 0.2 % on the 80 x 8 one (measured at most 0.12 %).
#[test]
fn turek_hron_csm1_and_csm2_bend_the_bar_to_the_benchmark() {
    use fdfsi::case::SolidMeshSpec;
    for (name, ux, uy) in [("turek-hron-csm1", -7.187e-3, -66.10e-3), ("turek-hron-csm2", -0.4690e-3, -16.97e-3)] {
        for (mesh, tol) in [("turek-hron-bar-40", 1e-2), ("turek-hron-bar-80", 2e-3)] {
            let (s, _) = run_with(name, |c| c.solid.first_mut().unwrap().mesh = SolidMeshSpec::Gmsh { file: format!("../meshes/{mesh}.msh").into() });
            let (ex, ey) = ((q(&s, "ux_A") - ux).abs() / ux.abs(), (q(&s, "uy_A") - uy).abs() / uy.abs());
            println!("{name} on {mesh}: ux_A {:.5e} ({ex:.2e}), uy_A {:.5e} ({ey:.2e})", q(&s, "ux_A"), q(&s, "uy_A"));
            assert!(ex < tol && ey < tol, "{name} on {mesh}: errors {ex:.2e}, {ey:.2e}");
        }
    }
}

/// The body force in the updated-Lagrangian form (the FSI solid's, weighted by the reference
/// volume `dV_n / J_n`) gives CSM1's total-Lagrangian solution: both forms discretise the same
/// equations (physics::solid's module doc), to the Newton tolerance (measured: equal to 13
/// digits; held at 1e-10).
#[test]
fn turek_hron_csm1_is_the_same_in_updated_lagrangian_form() {
    use fdfsi::discretize::solid::Lagrangian;
    let (total, _) = run("turek-hron-csm1");
    let (updated, _) = run_with("turek-hron-csm1", |c| c.solid.first_mut().unwrap().loading.mode = Lagrangian::Updated);
    for name in ["ux_A", "uy_A"] {
        let (a, b) = (q(&total, name), q(&updated, name));
        println!("{name}: total {a:.12e}, updated {b:.12e}");
        assert!((a - b).abs() < 1e-10 * a.abs(), "{name}: {a} vs {b}");
    }
}

/// Turek-Hron CSM3's first 0.5 s (CI), its first half swing: the bar released from rest falls to
/// the bottom of its swing, which the reference puts at `mean - amplitude` = -128.767 mm after
/// half a period, 0.4548 s (Turek & Hron; independent reference): within 1 % (measured
/// -129.315 mm, 0.43 %) and within two steps (measured 0.46 s), 2-3 Newton iterations a step.
#[test]
fn turek_hron_csm3_bar_falls_from_rest() {
    let (s, out) = run_with("turek-hron-csm3", |c| c.time.as_mut().unwrap().end = 0.5);
    assert_eq!(s.steps, 100);
    let h = history_columns(&out);
    let (t, uy) = (&h["time"], &h["uy_A"]);
    let bottom = (0..uy.len()).min_by(|&a, &b| uy[a].total_cmp(&uy[b])).unwrap();
    println!("CSM3: lowest u_y of A {:.6e} at t = {}", uy[bottom], t[bottom]);
    assert!(uy[..=bottom].windows(2).all(|w| w[1] < w[0]), "A falls to the bottom: {uy:?}");
    assert!((uy[bottom] + 128.767e-3).abs() < 1e-2 * 128.767e-3, "{}", uy[bottom]);
    assert!((t[bottom] - 0.5 / 1.0995).abs() <= 2.0 * 0.005, "{}", t[bottom]);
    assert!(h["newton_iterations"][1..].iter().all(|n| (2.0..=3.0).contains(n)), "{:?}", h["newton_iterations"]);
    // Less than a period: no oscillation statistics, and the run still completes.
    assert!(!s.quantities.contains_key("uy_A_frequency"));
}

/// The whole of Turek-Hron CSM3 (10 s, 2 000 BDF2 steps; about 95 s): mean, amplitude and
/// frequency of both displacements of A over the last period within 2 % of Turek & Hron's
/// (independent reference; measured at most 0.89 %).
#[test]
#[ignore = "about 95 s; run with --ignored"]
fn turek_hron_csm3_swings_at_the_benchmark_amplitude_and_frequency() {
    let (s, _) = run("turek-hron-csm3");
    assert_near_references(
        &s,
        &[
            ("ux_A_mean", -14.305e-3, 2e-2),
            ("ux_A_amplitude", 14.305e-3, 2e-2),
            ("ux_A_frequency", 1.0995, 2e-2),
            ("uy_A_mean", -63.607e-3, 2e-2),
            ("uy_A_amplitude", 65.160e-3, 2e-2),
            ("uy_A_frequency", 1.0995, 2e-2),
        ],
    );
}

#[test]
fn axisymmetric_cylinder_inflates_to_the_exact_radius() {
    let (s, out) = run("cylinder-inflation-axisymmetric");
    // EXACT-SOLUTIONS.md 1.4: P_i = 0.21541965495917 G inflates A = 1 to a = 1.3.
    let u = q(&s, "inner_radial_displacement");
    println!("cylinder inflation: a - A = {u:.9} (exact 0.3, error {:.1e})", (u - 0.3).abs());
    // Independent reference: the exact solution. README: to 4e-7 (measured 3.4e-7); held at 4e-6.
    assert!((u - 0.3).abs() < 4e-6, "{u}");
    // One history row per load increment, the probe growing with the load.
    let history = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let j = history.lines().next().unwrap().split(',').position(|c| c == "inner_radial_displacement").unwrap();
    let rows: Vec<Vec<f64>> = history.lines().skip(1).map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    assert_eq!(rows.len(), 4);
    assert!(rows.windows(2).all(|w| w[1][j] > w[0][j] && w[1][1] > w[0][1]), "{rows:?}");
    assert!((rows[3][j] - u).abs() < 1e-14);
    // Quadratic Newton in every load step: the last two residuals of each step fall fast.
    assert!(s.residual_norms.iter().all(|r| *r < 1e-10), "{:?}", s.residual_norms);
    // The inner face carries the pressure: the radial Cauchy stress of the innermost cells is
    // compressive, of the order of P_i.
    let grid = read_vtu(&read_pvd(&out.join("solution.pvd")).unwrap()[0].resolve(&out.join("solution.pvd"))).unwrap();
    let sigma = &grid.cell_array("cauchy_stress").unwrap().values;
    let s_rr_inner = sigma[4]; // cell 0 (at the inner face), component (r, r) = index 1*3+1
    assert!(s_rr_inner < 0.0 && s_rr_inner > -0.22, "{s_rr_inner}");
}

#[test]
fn slab_3d_poiseuille_is_exact_to_round_off() {
    let (s, _) = run("slab-3d-poiseuille");
    assert!((q(&s, "centre_velocity") - 1.5).abs() < 1e-10, "{}", q(&s, "centre_velocity"));
    let dp = q(&s, "pressure_at_x05") - q(&s, "pressure_at_x15");
    assert!((dp - 12.0).abs() < 1e-9, "{dp}");
    assert!((q(&s, "outlet_flux") - 0.5).abs() < 1e-12);
}

#[test]
fn quarter_pipe_converges_to_hagen_poiseuille_under_refinement() {
    // Straight-sided tetrahedra make the wall a polygon; as it refines, the axis velocity tends
    // to the Hagen-Poiseuille value 2 at about second order (the polygon's area error is O(h^2)).
    let mut errors = Vec::new();
    for (nr, na) in [(2, 4), (4, 8)] {
        let (s, _) = run_with("quarter-pipe-3d-stokes", |c| {
            if let Some(fdfsi::case::MeshSpec::Pipe { n_radial, n_axial, .. }) = c.mesh.as_mut() {
                *n_radial = nr;
                *n_axial = na;
            }
        });
        errors.push((q(&s, "axis_velocity") - 2.0).abs());
    }
    println!("quarter pipe: axis velocity errors {errors:?}");
    assert!(errors[1] < errors[0] / 3.0, "{errors:?}");
}

#[test]
fn model_problem_2_fsi_force_matches_the_dirichlet_twin() {
    let (fsi, out) = run("model-problem-2");
    let (twin, _) = run("skewed-plate-dirichlet");
    let f = [q(&fsi, "plate_force_x"), q(&fsi, "plate_force_y")];
    let g = [q(&twin, "plate_force_x"), q(&twin, "plate_force_y")];
    let diff = ((f[0] - g[0]).powi(2) + (f[1] - g[1]).powi(2)).sqrt() / (g[0].powi(2) + g[1].powi(2)).sqrt();
    println!("model problem 2: FSI force {f:?}, twin {g:?}, relative difference {diff:.3e}");
    // README: within 3e-6 of the twin (the case header: 2.7e-6; the meshes differ slightly);
    // held at 2.5e-5. The force itself, (1.18620, -0.84511), is a regression value (fdfsi
    // at 2ad5061).
    assert!(diff < 2.5e-5, "{diff}");
    assert!((f[0] - 1.18620).abs() < 1e-5 && (f[1] + 0.84511).abs() < 1e-5, "{f:?}");
    assert_has_provenance(&out);
    assert!((q(&fsi, "inlet_flux") + q(&fsi, "outlet_flux")).abs() < 1e-10);
    assert_eq!(fsi.steps, 12);
    assert!(q(&fsi, "coupling_facets") > 5.0);
    // Fluid and solid pieces in the series (steps 6 and 12).
    let entries = read_pvd(&out.join("solution.pvd")).unwrap();
    let names: Vec<&str> = entries.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(names, ["fluid", "solid", "gamma_f", "fluid", "solid", "gamma_f"]);
    // The gamma_f piece carries the multiplier: its integral is the force on the plate.
    let gamma_f = read_vtu(&entries[5].resolve(&out.join("solution.pvd"))).unwrap();
    let lambda = gamma_f.point_array("multiplier").unwrap();
    let mut force = [0.0; 2];
    for c in 0..gamma_f.num_cells() {
        let [a, b] = [gamma_f.cell(c)[0], gamma_f.cell(c)[1]];
        let len = (0..2).map(|d| (gamma_f.points[b][d] - gamma_f.points[a][d]).powi(2)).sum::<f64>().sqrt();
        for (d, f) in force.iter_mut().enumerate() {
            *f += 0.5 * len * (lambda.values[3 * a + d] + lambda.values[3 * b + d]);
        }
    }
    assert!((force[0] - q(&fsi, "coupling_force_x")).abs() < 1e-9 * f[0].abs(), "{force:?}");
    assert!((force[1] - q(&fsi, "coupling_force_y")).abs() < 1e-9 * f[1].abs(), "{force:?}");
    let history = std::fs::read_to_string(out.join("history.csv")).unwrap();
    assert_eq!(history.lines().count(), 13);
    assert!(history.lines().next().unwrap().contains("coupling_force_x"));
    for side in ["wss_upstream_side", "wss_downstream_side"] {
        let text = std::fs::read_to_string(out.join(format!("profiles/{side}.csv"))).unwrap();
        assert!(text.lines().count() > 10, "{side}");
    }
}

/// The rows of `history.csv` as (column name -> values).
fn history_columns(out: &Path) -> std::collections::BTreeMap<String, Vec<f64>> {
    let text = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let mut lines = text.lines();
    let names: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let mut cols: std::collections::BTreeMap<String, Vec<f64>> = names.iter().map(|n| (n.clone(), Vec::new())).collect();
    for line in lines {
        for (n, v) in names.iter().zip(line.split(',')) {
            cols.get_mut(n).unwrap().push(v.parse().unwrap());
        }
    }
    cols
}

/// Model problem 1 checks on a history: flux in = flux out every step and 3-5 Newton iterations
/// in every step. The flux balance holds to the linear solve's precision: 3e-15 with the direct
/// solver (round-off of fluxes of 0.2-1), 4.2e-13 with the default augmented-Lagrangian solver
/// (its FGMRES solves stop at the Eisenstat-Walker forcing term, not at round-off, and Newton at
/// `|R| <= 1e-10`; README); held at 1e-12.
fn check_model_problem_1(out: &Path, steps: usize) -> std::collections::BTreeMap<String, Vec<f64>> {
    let h = history_columns(out);
    assert_eq!(h["step"].len(), steps);
    for (k, (i, o)) in h["inlet_flux"].iter().zip(&h["outlet_flux"]).enumerate() {
        assert!((i + o).abs() < 1e-12, "step {}: flux in {i}, out {o}", k + 1);
    }
    let its = &h["newton_iterations"];
    assert!(its.iter().all(|n| (3.0..=5.0).contains(n)), "3-5 Newton iterations per step: {its:?}");
    h
}

#[test]
fn model_problem_1_first_steps_move_the_slab_and_conserve_volume() {
    // CI runs the first 0.3 period (24 steps): the rising inflow pushes the slab downstream.
    let (s, out) = run_with("model-problem-1", |c| c.time.as_mut().unwrap().end = 1.2);
    assert_eq!(s.steps, 24);
    let h = check_model_problem_1(&out, 24);
    let tip_x = &h["tip_displacement_x"];
    assert!(tip_x.windows(2).all(|w| w[1] > w[0]), "the tip moves downstream while the flow rises: {tip_x:?}");
    assert!(tip_x[23] > 0.05, "tip displacement {}", tip_x[23]);
    assert!(out.join("speed.png").exists() && out.join("plots/trajectory_tip_displacement.png").exists());
}

/// The built-in default case (`fdfsi run` with no case) is an FSI run, model problem 1's first
/// beat: CI runs its first half beat (40 steps, to peak inflow). It has solid and multiplier
/// unknowns (`summary.json`), the slab bends downstream as the flow rises (the tip 0.339 at t = 2),
/// volume is conserved every step, and it writes its picture, plots and animation.
#[test]
fn default_case_is_an_fsi_run_of_the_slab_in_one_beat() {
    assert_eq!(fdfsi::case::builtin::DEFAULT_CASE, include_str!("../cases/slab-one-beat.toml"));
    let (s, out) = run_with("slab-one-beat", |c| c.time.as_mut().unwrap().end = 2.0);
    assert_eq!(s.steps, 40);
    let dofs = &summary_json(&out)["dofs"];
    assert!(dofs["solid"].as_u64() > Some(0) && dofs["multiplier"].as_u64() > Some(0), "dofs {dofs}");
    let h = check_model_problem_1(&out, 40);
    let tip_x = &h["tip_displacement_x"];
    println!("default case: the tip at {:.4} downstream at t = 2", tip_x[39]);
    assert!([0, 9, 19, 39].windows(2).all(|w| tip_x[w[1]] > tip_x[w[0]]), "the tip moves downstream while the flow rises: {tip_x:?}");
    assert!(tip_x[39] > 0.3, "tip displacement {}", tip_x[39]);
    assert!(out.join("speed.png").exists() && out.join("plots/trajectory_tip_displacement.png").exists());
    // The animation: a GIF of the 20 output times.
    let gif = std::fs::read(out.join("animation.gif")).unwrap();
    assert!(gif.starts_with(b"GIF89a") && gif.len() > 100_000, "animation.gif: {} bytes", gif.len());
}

/// The whole case (4.5 periods; about 2.5 minutes): no failed step (360 rows), 3-5 Newton
/// iterations and flux in = flux out every step, the tip's largest excursion (0.34 downstream,
/// 0.12 up), and the tip path of period 4 repeating period 3 to 1.6 % (L2 over the period,
/// relative to the path's L2 norm; 4.4 % of the largest excursion at the worst instant). The
/// excursion and repeat values are regression values (fdfsi at 2ad5061), held to their printed
/// digits. With `FDFSI_LONG_RUNS` (see [`long_run`]) a finished
/// run is checked without running again.
#[test]
#[ignore = "about 2.5 minutes; run with --ignored"]
fn model_problem_1_motion_is_periodic() {
    let out = long_run("model-problem-1");
    let h = check_model_problem_1(&out, 360);
    assert_eq!(summary_json(&out)["dofs"]["total"].as_u64(), Some(29_679), "dofs at the last step (README; a regression value)");
    let (x, y) = (&h["tip_displacement_x"], &h["tip_displacement_y"]);
    let period = 80;
    let max_x = x.iter().fold(0.0f64, |m, v| m.max(*v));
    let max_y = y.iter().fold(0.0f64, |m, v| m.max(*v));
    println!("model problem 1: the tip moves up to {max_x:.4} downstream and {max_y:.4} up");
    assert!((max_x - 0.34).abs() < 0.006 && (max_y - 0.12).abs() < 0.006, "tip excursion ({max_x}, {max_y})");
    // The tip path of the period from step `a` against the one from step `b` (relative L2).
    let differ = |a: usize, b: usize| {
        let num: f64 = (0..period).map(|i| (x[a + i] - x[b + i]).powi(2) + (y[a + i] - y[b + i]).powi(2)).sum();
        (num / (0..period).map(|i| x[b + i].powi(2) + y[b + i].powi(2)).sum::<f64>()).sqrt()
    };
    let (a, b) = (2 * period, 3 * period); // periods 3 and 4
    let repeat = differ(a, b);
    let excursion = (0..period).map(|i| x[b + i].hypot(y[b + i])).fold(0.0f64, f64::max);
    let worst = (0..period).map(|i| (x[a + i] - x[b + i]).hypot(y[a + i] - y[b + i])).fold(0.0f64, f64::max) / excursion;
    println!("model problem 1: tip path of period 4 vs period 3: {repeat:.4} (L2, relative), {worst:.4} at the worst instant");
    assert!((repeat - 0.016).abs() < 0.001, "{repeat}");
    assert!((worst - 0.044).abs() < 0.002, "{worst}");
    // The start from rest: periods 2 and 3 differ by 1.9 %, periods 1 and 2 by 10 %.
    let (d23, d12) = (differ(period, 2 * period), differ(0, period));
    println!("model problem 1: periods 2 vs 3 {d23:.4}, 1 vs 2 {d12:.4}");
    assert!((d23 - 0.019).abs() < 0.001 && (d12 - 0.10).abs() < 0.006, "{d23} {d12}");
}

/// The values of a profile CSV (last column).
fn profile_values(out: &Path, name: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(out.join(format!("profiles/{name}.csv"))).unwrap();
    text.lines().skip(1).map(|l| l.rsplit(',').next().unwrap().parse().unwrap()).collect()
}

/// What a membrane run (model problems 3 and 4) claims of its equilibrium at t = 6, as fractions
/// of the applied traction 1 (README and the case headers; measured values of that run).
struct EquilibriumClaims {
    /// |upstream pressure - 1| and |downstream pressure|.
    pressures: [f64; 2],
    /// The last max fluid speed over its peak.
    speed: f64,
    /// The largest |p - 1| and |p| in the cells upstream and downstream of gamma_f.
    sides: [f64; 2],
    /// The largest |lambda - p n| at the vertices of gamma_f (a discretisation error, O(h)).
    traction: f64,
}

/// Model problems 3 and 4 at equilibrium: the upstream pressure is the applied traction and the
/// downstream one zero, the fluid is at rest and the pressure jumps exactly on gamma_f: the cells
/// on either side of it hold their side's pressure (no smearing). The multiplier, the traction on
/// the membrane, is `p n` (`n` the facet normal, its `axial` component positive) at every vertex
/// of every gamma_f facet. The round-off-like claims (pressures, speed, sides) are held at 10
/// times the claim, the traction (a discretisation error) at 1.25 times. Returns the history.
fn check_membrane_equilibrium(out: &Path, axial: usize, claims: &EquilibriumClaims) -> std::collections::BTreeMap<String, Vec<f64>> {
    let h = history_columns(out);
    let summary = summary_json(out);
    let q = |name: &str| summary["quantities"][name].as_f64().unwrap_or_else(|| panic!("quantity {name} missing"));
    let applied = q("applied_traction");
    assert!((applied - 1.0).abs() < 1e-12, "the traction is held at 1 after the rise: {applied}");
    let (up, down) = (q("upstream_pressure"), q("downstream_pressure"));
    println!("equilibrium: upstream pressure {up:.8}, downstream {down:.3e}, applied {applied}");
    assert!((up - applied).abs() < 10.0 * claims.pressures[0] * applied, "upstream pressure {up}");
    assert!(down.abs() < 10.0 * claims.pressures[1] * applied, "downstream pressure {down}");
    let speed = &h["max_fluid_speed"];
    let peak = speed.iter().fold(0.0f64, |m, v| m.max(*v));
    let last = *speed.last().unwrap();
    println!("max fluid speed: peak {peak:.4e}, last {last:.4e} ({:.2e} of the peak)", last / peak);
    assert!(peak > 0.01 && last < 10.0 * claims.speed * peak, "speed {last} of peak {peak}");
    for ((side, value), claim) in [("pressure_upstream_side", applied), ("pressure_downstream_side", 0.0)].into_iter().zip(claims.sides) {
        let p = profile_values(out, side);
        assert!(p.len() > 10, "{side}: {} points", p.len());
        let worst = p.iter().map(|v| (v - value).abs()).fold(0.0f64, f64::max);
        println!("{side}: {} points, max |p - {value}| = {worst:.3e}", p.len());
        assert!(worst < 10.0 * claim * applied, "{side}: pressure smeared across gamma_f by {worst}");
    }
    let entries = read_pvd(&out.join("solution.pvd")).unwrap();
    let last = entries.iter().rev().find(|e| e.name == "gamma_f").unwrap();
    let gamma_f = read_vtu(&last.resolve(&out.join("solution.pvd"))).unwrap();
    let lambda = gamma_f.point_array("multiplier").unwrap();
    // |lambda - p n| at the vertices of every facet, n the facet's unit normal (axial part > 0).
    let mut dev = 0.0f64;
    for c in 0..gamma_f.num_cells() {
        let v = gamma_f.cell(c);
        let x = |k: usize, d: usize| gamma_f.points[v[k]][d];
        let mut n = if v.len() == 2 {
            [-(x(1, 1) - x(0, 1)), x(1, 0) - x(0, 0), 0.0]
        } else {
            let (a, b): ([f64; 3], [f64; 3]) = (std::array::from_fn(|d| x(1, d) - x(0, d)), std::array::from_fn(|d| x(2, d) - x(0, d)));
            [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
        };
        let len = n.iter().map(|v| v * v).sum::<f64>().sqrt() * n[axial].signum();
        n.iter_mut().for_each(|v| *v /= len);
        for &p in v {
            let d: f64 = (0..3).map(|a| (lambda.values[3 * p + a] - applied * n[a]).powi(2)).sum::<f64>().sqrt();
            dev = dev.max(d);
        }
    }
    println!("multiplier on gamma_f: max |lambda - p n| = {dev:.3e}");
    assert!(dev < 1.25 * claims.traction * applied, "the traction on gamma_f is not p n: {dev}");
    h
}

#[test]
fn model_problem_3_reaches_equilibrium_with_the_pressure_jump_on_gamma_f() {
    let (s, out) = run("model-problem-3");
    assert_eq!(s.steps, 60);
    assert_eq!(s.dofs["total"], 7_927, "README");
    let h = check_membrane_equilibrium(&out, 0, &MODEL_PROBLEM_3);
    // Overdamped: the membrane bulges downstream monotonically (to round-off at the end).
    let w = &h["centre_displacement"];
    assert!(w.windows(2).all(|p| p[1] > p[0] - 1e-9), "{w:?}");
    // Regression value (fdfsi at 2ad5061), the reference of every model problem 4 comparison.
    assert!((w.last().unwrap() - 0.104689).abs() < 2e-6, "centre displacement {}", w.last().unwrap());
    assert!(out.join("plots/centre_displacement.png").exists());
}

/// README and cases/model-problem-3.toml: upstream 1 - 1.1e-8, downstream 1.1e-8, speed 5.8e-6 of
/// its peak, the cells on both sides 1 and 0 to 8e-6, the traction p n to 1.2e-2.
const MODEL_PROBLEM_3: EquilibriumClaims = EquilibriumClaims { pressures: [1.1e-8, 1.1e-8], speed: 5.8e-6, sides: [8e-6, 8e-6], traction: 1.2e-2 };

/// Model problem 3 on a mesh twice as fine (80 x 20 fluid cells, 20 membrane cells): the
/// equilibrium centre displacement moves by less than 1e-4 of itself (0.104689 -> 0.104680, a
/// regression value of fdfsi at 2ad5061): the axisymmetric reference of model problem 4 is
/// converged far below the 3D gaps (0.26 %, 0.10 %).
#[test]
fn model_problem_3_centre_displacement_is_converged_in_the_mesh() {
    use fdfsi::case::{MeshSpec, SolidMeshSpec};
    let (_, out) = run_with("model-problem-3", |c| {
        c.mesh = Some(MeshSpec::Rectangle { x: [0.0, 4.0], y: [0.0, 1.0], n: [80, 20] });
        let solid = c.solid.first_mut().unwrap();
        solid.mesh = SolidMeshSpec::Rectangle { x: [1.975, 2.025], y: [0.0, 1.0], n: [1, 20] };
    });
    let w = *history_columns(&out)["centre_displacement"].last().unwrap();
    println!("model problem 3, fine mesh: centre displacement {w:.7}");
    assert!((w - 0.104680).abs() < 2e-6, "{w}");
    assert!((w - 0.104689).abs() < 1e-4 * w);
}

#[test]
fn model_problem_4_coarse_first_steps_seal_the_pipe_and_bulge_the_membrane() {
    // CI runs the first 5 steps on a coarser mesh (468 tetrahedra, 30 hexahedra); the full case
    // is model_problem_4_follows_model_problem_3 below.
    use fdfsi::case::{MeshSpec, SolidMeshSpec};
    let (s, out) = run_with("model-problem-4", |c| {
        c.mesh = Some(MeshSpec::Pipe { radius: 1.0, length: 4.0, n_radial: 4, n_axial: 6, quarter: true });
        let solid = c.solid.first_mut().unwrap();
        solid.mesh = SolidMeshSpec::QuarterDisc { radius: 1.0, z: [1.975, 2.025], n_core: 3, n_ring: 2, n_layers: 1 };
        c.time.as_mut().unwrap().end = 0.5;
    });
    assert_eq!(s.steps, 5);
    let h = history_columns(&out);
    // gamma_f covers the whole section: the 26 triangles of the pipe's section at least.
    assert!(h["coupling_facets"].iter().all(|&n| n >= 26.0), "{:?}", h["coupling_facets"]);
    let w = &h["centre_displacement"];
    assert!(w.windows(2).all(|p| p[1] > p[0]) && w[4] > 0.0, "the membrane bulges downstream: {w:?}");
    // The membrane holds the pressure: upstream follows the rising traction, downstream stays small.
    for k in 0..5 {
        let (a, up, down) = (h["applied_traction"][k], h["upstream_pressure"][k], h["downstream_pressure"][k]);
        assert!((up - a).abs() < 0.05 * a && down.abs() < 0.05 * a, "step {}: applied {a}, upstream {up}, downstream {down}", k + 1);
    }
    // The fluid pushes the membrane along +z (the force of the fluid on the solid).
    assert!(h["coupling_force_z"][4] > 0.0);
    let entries = read_pvd(&out.join("solution.pvd")).unwrap();
    let names: Vec<&str> = entries.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(names, ["fluid", "solid", "gamma_f"]);
    assert!(out.join("pictures/gamma_step_0005.png").exists(), "the picture of gamma_s and gamma_f");
    assert!(out.join("speed.png").exists(), "the speed on a plane through the membrane");
}

#[test]
fn model_problem_4_fine_mesh_seals_the_pipe_at_rest() {
    // The run takes about 2.5 hours (model_problem_4_fine_mesh_closes_the_equilibrium_gap below); CI checks
    // the case: meshes, the adaptation at t = 0, the dofs.
    let (case, dir) = case_file("model-problem-4-fine");
    let summary = fdfsi::run::check::check(&case, "model-problem-4-fine.toml", &dir).unwrap();
    assert!(summary.description.contains("4662 cells") && summary.description.contains("189 cells"), "{}", summary.description);
    // gamma_f crosses the layer of cells between z = 12/7 and 16/7: each of its 3 x 222
    // tetrahedra is cut in a triangle or a quadrilateral (two facets), so 666 to 1332 facets; the
    // adaptation makes 888 (a regression count).
    let facets: usize =
        summary.description.split(" coupling elements").next().and_then(|t| t.rsplit(' ').next()).and_then(|n| n.parse().ok()).unwrap();
    assert!((666..=1332).contains(&facets), "{}", summary.description);
    assert_eq!(facets, 888, "{}", summary.description);
    assert_eq!(summary.steps, 60);
    // gamma_f covers gamma_s up to the wall: the flat membrane face is the quarter of the
    // 72-gon, area (pi/4) (72 / (2 pi)) sin(2 pi / 72) = 0.784398. (The membrane's rim points
    // between the wall's vertices lie off the wall's planes by round-off; before the cut test
    // allowed for that, wall edges through the rim were missed and gamma_f had holes along the
    // rim: 873 facets.)
    let out = tempfile::tempdir().unwrap();
    let a = fdfsi::run::adapt::adapt_case(&case, &dir, out.path()).unwrap();
    let polygon = std::f64::consts::FRAC_PI_4 * 72.0 / (2.0 * std::f64::consts::PI) * (2.0 * std::f64::consts::PI / 72.0).sin();
    assert!((a.gamma_s_measure - polygon).abs() < 1e-12, "gamma_s {}", a.gamma_s_measure);
    assert!((a.gamma_f_measure - a.gamma_s_measure).abs() < 1e-12, "gamma_f {} vs gamma_s {}", a.gamma_f_measure, a.gamma_s_measure);
}

#[test]
fn model_problem_4_has_the_papers_cell_counts() {
    // README: 3 600 P2+ tetrahedra and 84 Q2 hexahedra (the paper: 3 600 and 80).
    let (case, dir) = case_file("model-problem-4");
    let summary = fdfsi::run::check::check(&case, "model-problem-4.toml", &dir).unwrap();
    assert!(summary.description.contains("3600 cells") && summary.description.contains("84 cells"), "{}", summary.description);
}

fn case_file(name: &str) -> (Case, PathBuf) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    (Case::read(&dir.join(format!("{name}.toml"))).unwrap(), dir)
}

/// The paths whose content decides a run's numbers: the code, the meshes, the locked
/// dependencies (the case is compared on its own; a case header's comments do not count). The
/// same as `build.rs`'s, which decide `git_modified`.
const CODE_PATHS: &[&str] = &["src", "crates", "meshes", "Cargo.toml", "Cargo.lock", "build.rs"];

/// Refuses a run made by other code than the code under test: every build in `builds` (of a
/// finished run's `summary.json` provenance, or of an unfinished run's checkpoint) must be of a
/// known commit, unmodified, whose [`CODE_PATHS`] equal this checkout's (`git diff` of the commit
/// against the working tree, and no untracked files there).
fn assert_builds_are_this_code<'a>(out: &Path, builds: impl IntoIterator<Item = &'a fdfsi::io::provenance::Build>) {
    let git = |args: &[&str]| std::process::Command::new("git").current_dir(env!("CARGO_MANIFEST_DIR")).args(args).args(CODE_PATHS).output();
    let untracked = git(&["ls-files", "--others", "--exclude-standard", "--"]).map(|o| o.stdout).unwrap_or_default();
    assert!(untracked.is_empty(), "untracked files in the code: {}", String::from_utf8_lossy(&untracked));
    let mut any = false;
    for b in builds {
        any = true;
        assert!(b.is_reproducible(), "{}: made by a build of modified or unknown source ({b:?}); move it away to run again", out.display());
        let same = git(&["diff", "--quiet", &b.git_commit, "--"]).is_ok_and(|o| o.status.success());
        assert!(same, "{}: made by commit {} whose code differs from this checkout's; move it away to run again", out.display(), b.git_commit);
    }
    assert!(any, "{}: no build is recorded (made before 2ad5061); move it away to run again", out.display());
}

/// Refuses a finished run made by other code (see [`assert_builds_are_this_code`]) or whose
/// `case.toml` changed after it.
fn assert_made_by_this_code(out: &Path) {
    assert_builds_are_this_code(out, provenance(out).builds());
}

/// The output folder of a long case run. With `FDFSI_LONG_RUNS=DIR` the case runs into
/// `DIR/NAME` with a checkpoint every step, resumes there if a checkpoint is there, and is not run
/// again if a finished run is there (its `summary.json`; its `case.toml` must be the case's up to
/// `[solver.linear]`, which changes only round-off, and its provenance this code, see
/// [`assert_made_by_this_code`]), so runs made with `fdfsi run CASE --out DIR/NAME` are checked
/// without running again.
fn long_run(name: &str) -> PathBuf {
    let Some(dir) = std::env::var_os("FDFSI_LONG_RUNS") else { return run(name).1 };
    let out = PathBuf::from(dir).join(name);
    let (case, cases) = case_file(name);
    if out.join("summary.json").exists() {
        let mut used = Case::from_toml_str(&std::fs::read_to_string(out.join("case.toml")).unwrap(), "case.toml").unwrap();
        used.solver.linear = case.solver.linear.clone();
        assert_eq!(used.to_toml(), case.to_toml(), "{} was run with another case than cases/{name}.toml", out.display());
        assert_made_by_this_code(&out);
        return out;
    }
    let (case, options) = if Checkpoint::path(&out).exists() {
        // An interrupted run goes on only if it is of this case and this code.
        let (mut used, options) = RunOptions::resume(&out).unwrap();
        let checkpoint = options.resume.as_ref().unwrap();
        assert_builds_are_this_code(&out, &checkpoint.builds);
        let linear = std::mem::replace(&mut used.solver.linear, case.solver.linear.clone());
        assert_eq!(used.to_toml(), case.to_toml(), "{} was started with another case than cases/{name}.toml", out.display());
        used.solver.linear = linear;
        (used, options)
    } else {
        (case, RunOptions::new(out.clone(), cases))
    };
    run_case(&case, &RunOptions { checkpoint_every: Some(1), ..options }, &mut |_: &str| {}).unwrap();
    out
}

/// cases/model-problem-4.toml: upstream 1 - 1.1e-7, downstream 9e-8, speed 2.4e-5 of its peak,
/// the cells on both sides of gamma_f within 4.8e-4, the traction p n to 8.7e-3.
const MODEL_PROBLEM_4: EquilibriumClaims = EquilibriumClaims { pressures: [1.1e-7, 9e-8], speed: 2.4e-5, sides: [4.8e-4, 4.8e-4], traction: 8.7e-3 };

/// README and cases/model-problem-4-fine.toml: upstream 1 - 6e-7, downstream 9e-7, speed 6.9e-5
/// of its peak, the cells on both sides 1 and 0 to 3.3e-4 / 3.9e-4, the traction p n to 9.1e-3.
const MODEL_PROBLEM_4_FINE: EquilibriumClaims =
    EquilibriumClaims { pressures: [6e-7, 9e-7], speed: 6.9e-5, sides: [3.3e-4, 3.9e-4], traction: 9.1e-3 };

/// A model problem 4 run against model problem 3: 60 steps, its dofs at the last step, its
/// equilibrium claims; returns the worst deviation of the centre displacement over the transient
/// and the equilibrium gap, both relative to model problem 3's final value, and its final value.
fn compare_with_model_problem_3(out3: &Path, out4: &Path, claims: &EquilibriumClaims, dofs: u64) -> (f64, f64, f64) {
    assert_eq!(history_columns(out4)["time"].len(), 60, "{}: 60 steps", out4.display());
    assert_eq!(summary_json(out4)["dofs"]["total"].as_u64(), Some(dofs), "{}: dofs at the last step", out4.display());
    check_membrane_equilibrium(out4, 2, claims);
    let w3 = history_columns(out3)["centre_displacement"].clone();
    let w4 = history_columns(out4)["centre_displacement"].clone();
    let scale = *w3.last().unwrap();
    let worst = w4.iter().zip(&w3).map(|(a, b)| (a - b).abs()).fold(0.0f64, f64::max) / scale;
    let last = *w4.last().unwrap();
    let gap = (last - scale).abs() / scale;
    println!("{}: centre displacement {last:.6} against {scale:.6} axisymmetric: gap {gap:.4}, transient {worst:.4}", out4.display());
    (worst, gap, last)
}

/// The centre displacement of model problem 4 on the paper's mesh follows model problem 3
/// (README: within 0.53 % of the final value over the whole transient; equilibrium 0.104418, a
/// gap of 0.26 %), gamma_f has 100 to 180 facets, and the equilibrium claims of the case header
/// hold. Regression values (fdfsi at 2ad5061), held to their printed digits. About 30-45 minutes:
/// run with --ignored (and `FDFSI_LONG_RUNS`, see [`long_run`], to check finished runs).
#[test]
#[ignore = "about 20 minutes (30-45 with method = direct); run with --ignored"]
fn model_problem_4_follows_model_problem_3() {
    let out3 = long_run("model-problem-3");
    let out4 = long_run("model-problem-4");
    let (worst, gap, last) = compare_with_model_problem_3(&out3, &out4, &MODEL_PROBLEM_4, 75_018);
    let facets = &history_columns(&out4)["coupling_facets"];
    assert!(facets.iter().all(|n| (100.0..=180.0).contains(n)), "model problem 4: gamma_f has 100 to 180 facets: {facets:?}");
    assert!((worst - 0.0053).abs() < 0.0003, "3D vs axisymmetric over the transient: {worst}");
    assert!((last - 0.104418).abs() < 2e-6, "equilibrium {last}");
    assert!((gap - 0.0026).abs() < 0.0001, "gap {gap}");
}

/// On the fine mesh model problem 4 follows model problem 3 within 0.89 % over the transient, and
/// refinement closes the equilibrium gap (0.104584, 0.10 % against the coarse mesh's 0.26 %); its
/// equilibrium claims hold. Regression values of session 5 (recorded at 86935e3), held to their
/// printed digits. About three hours with the coarse run (the fine one 2.5): run with --ignored
/// (and `FDFSI_LONG_RUNS`, see [`long_run`], to check finished runs).
#[test]
#[ignore = "about three hours; run with --ignored"]
fn model_problem_4_fine_mesh_closes_the_equilibrium_gap() {
    let out3 = long_run("model-problem-3");
    let (_, gap, _) = compare_with_model_problem_3(&out3, &long_run("model-problem-4"), &MODEL_PROBLEM_4, 75_018);
    let (worst, gap_fine, last) = compare_with_model_problem_3(&out3, &long_run("model-problem-4-fine"), &MODEL_PROBLEM_4_FINE, 143_922);
    assert!((worst - 0.0089).abs() < 0.0003, "fine 3D mesh vs axisymmetric over the transient: {worst}");
    assert!((last - 0.104584).abs() < 2e-6, "equilibrium {last}");
    assert!((gap_fine - 0.0010).abs() < 0.0001, "gap {gap_fine}");
    assert!(gap_fine < gap, "refinement closes the equilibrium gap: {gap} -> {gap_fine}");
}

/// Upward zero crossings of `v - mean(v)` (linear interpolation in `t`).
fn upward_crossings(t: &[f64], v: &[f64]) -> Vec<f64> {
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    (1..v.len()).filter(|&i| v[i - 1] < mean && v[i] >= mean).map(|i| t[i - 1] + (t[i] - t[i - 1]) * (mean - v[i - 1]) / (v[i] - v[i - 1])).collect()
}

/// Schaefer-Turek 2D-2 (Re = 100) over t in [5, 8], eight shedding periods, on the coarse mesh
/// (BENCHMARKS.md). Independent reference (Schaefer & Turek 1996): Strouhal number 0.295-0.305,
/// met. The maximum drag (3.2174) and lift (0.954) are regression values (fdfsi at 2ad5061) that
/// lie *below* the reference ranges 3.22-3.24 and 0.99-1.01 on this mesh and time step (0.08 %
/// and 3.6 % below their lower ends): asserted as regression values, not as agreement.
#[test]
#[ignore = "about 15 minutes; run with --ignored"]
fn cylinder_re100_sheds_at_the_benchmark_strouhal_number() {
    let out = long_run("cylinder-re100");
    let h = history_columns(&out);
    assert_eq!(h["time"].len(), 801, "the initial state and 800 steps");
    let from = h["time"].iter().position(|&t| t >= 5.0 - 1e-9).unwrap();
    let (t, cd, cl) = (&h["time"][from..], &h["drag_coefficient"][from..], &h["lift_coefficient"][from..]);
    let up = upward_crossings(t, cl);
    let period = (up.last().unwrap() - up[0]) / (up.len() - 1) as f64;
    // St = f D / U_mean with D = 0.1, U_mean = 1.
    let strouhal = 0.1 / period;
    let cd_max = cd.iter().fold(f64::MIN, |m, v| m.max(*v));
    let cl_max = cl.iter().fold(f64::MIN, |m, v| m.max(*v));
    let cl_min = cl.iter().fold(f64::MAX, |m, v| m.min(*v));
    println!("Re = 100: {} periods, period {period:.4}, St {strouhal:.4}, max drag {cd_max:.4}, lift {cl_min:.3} .. {cl_max:.3}", up.len() - 1);
    assert_eq!(up.len() - 1, 8, "eight whole periods between upward crossings in [5, 8]: {up:?}");
    assert_eq!(summary_json(&out)["dofs"]["total"].as_u64(), Some(36_596));
    assert!((0.295..=0.305).contains(&strouhal), "Strouhal number {strouhal}");
    assert!((strouhal - 0.2982).abs() < 2e-4, "Strouhal number {strouhal} (regression 0.2982)");
    assert!((cd_max - 3.2174).abs() < 2e-4, "max drag {cd_max} (regression 3.2174)");
    assert!((cl_max - 0.954).abs() < 2e-3 && (cl_min + 0.991).abs() < 2e-3, "lift {cl_min} .. {cl_max} (regression -0.991 .. 0.954)");
}

/// The fluid film (issue 17): the force on a rigid cylinder approaching a wall in Stokes flow,
/// with the gap spanning 4 fluid cells, against the bipolar-coordinate force and its lubrication
/// limit (the case's header).
#[test]
fn fluid_film_force_matches_the_lubrication_force() {
    let (s, out) = run("fluid-film");
    assert_has_provenance(&out);
    let (r, h) = (1.0_f64, 0.02_f64);
    let alpha = (1.0 + h / r).acosh();
    let exact = 4.0 * std::f64::consts::PI / (alpha - alpha.tanh());
    let lubrication = 3.0 * 2f64.sqrt() * std::f64::consts::PI * (r / h).powf(1.5);
    let force = q(&s, "coupling_force_y");
    let (e_exact, e_lub) = ((force - exact) / exact, (force - lubrication) / lubrication);
    println!("fluid film, h = {h}: force {force:.2}, bipolar {exact:.2} ({e_exact:+.2e}), lubrication {lubrication:.2} ({e_lub:+.2e})");
    assert!(e_lub.abs() < 0.05, "the issue's 5 % of the lubrication force: {e_lub:.2e}");
    assert!(e_exact.abs() < 2e-3, "the bipolar force: {e_exact:.2e}");
}

/// cases/valve-2d.toml over its first 30 steps (t = 0.03, the start of ejection): the ventricle's
/// pressure rises above the aorta's, the flow through the valve is forward and accelerates, the
/// leaflet swings open (its sweep downstream, its tip rising from 4 mm) and the aortic pressure
/// rises, the outlet's pressure the Windkessel's `R_p Q + P_c`.
#[test]
fn valve_2d_opens_at_the_start_of_ejection() {
    let (_, out) = run_with("valve-2d", |c| {
        let time = c.time.as_mut().unwrap();
        time.end = 0.03;
        time.output_every = 1000;
        c.output.animation = Some(false);
    });
    let h = history_columns(&out);
    assert_eq!(h["time"].len(), 30, "every step done");
    let (q, sweep, gap) = (&h["valve_flux"], &h["leaflet_sweep"], &h["bottom_gap_min"]);
    assert!(q.windows(2).all(|w| w[1] > w[0] && w[0] > 0.0), "forward and accelerating: {q:?}");
    assert!(sweep.iter().all(|s| *s > 0.0), "the leaflet swings downstream");
    assert!((gap[0] - 4.0).abs() < 0.05 && gap[29] > gap[0] + 0.5, "the tip rises from 4 mm: {} to {}", gap[0], gap[29]);
    assert!(h["bottom_contact_force"].iter().all(|f| *f == 0.0), "open");
    let (p_lv, p_ao) = (&h["p_lv"], &h["p_ao"]);
    assert!(p_lv.iter().zip(p_ao).all(|(v, a)| v > a), "the ventricle's pressure above the aorta's");
    assert!(h["outlet_pressure"].windows(2).all(|w| w[1] > w[0]), "the aortic pressure rises");
    // The outlet's pressure is the Windkessel's, R_p Q + P_c (R_p = 0.3).
    let (p_out, q_out, p_c) = (&h["outlet_pressure"], &h["outlet_flux"], &h["outlet_capacitor_pressure"]);
    assert!((0..30).all(|k| (p_out[k] - 0.3 * q_out[k] - p_c[k]).abs() < 1e-9 * p_out[k]));
    println!("valve-2d at t = 0.03: valve flux {:.1} mm^2/s, tip gap {:.3} mm, max speed {:.1} mm/s", q[29], gap[29], h["max_speed"][29]);
}

/// cases/valve-3d-sector.toml over its first 2 steps: the ventricle's pressure above the aorta's,
/// the flow through the valve forward, the leaflet's free edge moving away from the axis and
/// held on its mirror plane (the roller of the inclined symmetry plane, exactly), and the
/// geometric orifice area at rest against an independent computation: shapely's union of the
/// projected analytic leaflet surface (meshes/make_valve_3d.py's map, 400 x 400 quadrilaterals)
/// subtracted from the exact annulus sector, 125.271 mm^2 for the whole valve (127.428 for the
/// leaflet before session 44)
/// (meshes/valve_3d_open_area.py; fdfsi: the faceted fluid section and the Q2 leaflet's facets,
/// rasterised); and its animations (the speed on the plane of speed.png, the solid from the aorta).
#[test]
fn valve_3d_sector_opens_on_its_symmetry_planes() {
    let (_, out) = run_with("valve-3d-sector", |c| {
        let time = c.time.as_mut().unwrap();
        time.end = 0.002;
        time.output_every = 1;
    });
    let h = history_columns(&out);
    assert_eq!(h["time"].len(), 2, "every step done");
    // The animation of a 3D run: the speed on the plane of speed.png at both steps, and the
    // leaflet seen along the flow with its 5 mirror images (src/io/view.rs).
    for (name, least) in [("animation.gif", 50_000), ("solid.gif", 20_000)] {
        let gif = std::fs::read(out.join(name)).unwrap();
        assert!(gif.starts_with(b"GIF89a") && gif.len() > least, "{name}: {} bytes", gif.len());
    }
    // Fields whose files are gone (a run resumed from its checkpoint alone) are left out: one
    // time is left, nothing to animate, and no error.
    std::fs::remove_file(out.join("solution_fluid_000000.vtu")).unwrap();
    assert!(matches!(fdfsi::io::animation::animate_run(&out), Ok(None)));
    let (q, opening, off) = (&h["valve_flux"], &h["tip_opening"], &h["tip_off_plane"]);
    assert!(q.iter().all(|v| *v > 0.0), "forward flow: {q:?}");
    assert!(opening[0] > 0.0 && opening[1] > opening[0], "the free edge moves away from the axis: {opening:?}");
    assert!(off.iter().zip(opening).all(|(o, u)| o.abs() <= 1e-12 * u.abs()), "on the mirror plane: {off:?}");
    assert!(h["p_lv"].iter().zip(&h["p_ao"]).all(|(v, a)| v > a), "the ventricle's pressure above the aorta's");
    assert!(h["ventricular_contact_force"].iter().all(|f| *f == 0.0), "open");
    let area = h["open_area"][0];
    assert!((area / 125.271 - 1.0).abs() < 5e-3, "open area at rest {area} mm^2 against 125.271");
    println!("valve-3d-sector after 2 steps: valve flux {:.1} mm^3/s, tip opening {:.3e} mm, open area {area:.2} mm^2", q[1], opening[1]);
}

/// cases/valve-3d.toml, the whole valve, over its first step against the sector model's: the
/// whole valve's flux and open area those of the sector (which scales its own by 6), the middle
/// of leaflet 1's free edge where the sector's goes and on leaflet 1's mirror plane. The meshes
/// are the sector's images, but the adaptation differs next to the sector's planes (nodes there
/// are boundary nodes of the sector, inner nodes of the whole), hence not round-off. Measured
/// (session 33): flux 1.0e-3, open area 3.1e-5, tip 2.3e-4, pressures 4e-7 apart; session 34,
/// with gamma_f whole on the curved leaflets: flux 1.2e-4, open area 3.3e-5, tip 2.2e-4,
/// pressures 4e-7; session 38, G = 0.3 MPa: flux 1.7e-4, open area 2e-7, tip 5.9e-5, pressures
/// 6e-8 (450 s beside a long run); held at 3e-3.
/// Ignored: 380 810 unknowns (6 times the sector's; 372 611 with the leaflet before session 44), 11.3 GiB and about 6 minutes here.
#[test]
#[ignore = "the whole valve: 380 810 unknowns, for a large machine"]
fn valve_3d_whole_valve_takes_its_first_step_as_its_sector() {
    let one_step = |c: &mut Case| {
        let time = c.time.as_mut().unwrap();
        time.end = 0.001;
        time.output_every = 1000;
    };
    let (_, whole) = run_with("valve-3d", one_step);
    let (_, sector) = run_with("valve-3d-sector", one_step);
    let (w, s) = (history_columns(&whole), history_columns(&sector));
    for name in ["valve_flux", "open_area", "tip_opening", "p_lv", "p_ao"] {
        let (a, b) = (w[name][0], s[name][0]);
        println!("valve-3d after 1 step: {name} {a:.6e}, the sector's {b:.6e} ({:+.2e})", a / b - 1.0);
        assert!((a / b - 1.0).abs() < 3e-3, "{name}: the whole valve's {a}, the sector's {b}");
    }
    let off = w["tip_off_plane"][0];
    assert!(off.abs() <= 1e-3 * w["tip_opening"][0].abs(), "leaflet 1's middle off its mirror plane by {off}");
}

/// cases/valve-3d-sector.toml over its three cardiac cycles, issue 19's checks (the whole valve's
/// figures: the case scales the sector's by 6): every step done (3.5 beats, the cycles from
/// mid-diastole); the valve opens and closes in every cycle with the leaflet in contact; forward
/// (stroke) volume 60-75 ml, peak jet 1.0-1.7 m/s (the largest speed beyond the annulus over the
/// forward flow, `jet_speed`), geometric open area 2.5-4 cm^2, mean
/// systolic gradient below 10 mmHg, leak below 1 % of the forward volume, cycle 3 within 2 % of
/// cycle 2. With `FDFSI_LONG_RUNS` (see [`long_run`]) a finished run is checked without running
/// again; an unfinished one goes on from its checkpoint.
#[test]
#[ignore = "about 16 hours on 2 cores; run with --ignored"]
fn valve_3d_sector_opens_and_closes_over_three_cardiac_cycles() {
    let out = long_run("valve-3d-sector");
    let s = summary_json(&out);
    assert_eq!(s["steps"].as_u64(), Some(2800), "every step done");
    let q = |name: &str| s["quantities"][name].as_f64().unwrap_or(f64::NAN);
    let cycle = |k: usize, name: &str| q(&format!("cycle_{k}_{name}"));
    let mmhg = 133.322;
    for k in 1..=3 {
        let (forward, leak) = (cycle(k, "forward_volume"), cycle(k, "leak_volume"));
        let (jet, area, gradient) = (cycle(k, "forward_peak_jet_speed"), cycle(k, "peak_open_area"), cycle(k, "forward_mean_transvalvular_gradient"));
        println!(
            "valve-3d-sector cycle {k}: forward {:.2} ml, backward {:.2} ml, leak {:.3} ml; opens at {:.3} s, closes at {:.3} s (from \
             mid-diastole); peak jet {:.2} m/s, peak open area {:.2} cm^2, mean systolic gradient {:.1} mmHg",
            forward / 1e3,
            cycle(k, "backward_volume") / 1e3,
            leak / 1e3,
            cycle(k, "opening_time"),
            cycle(k, "closing_time"),
            jet / 1e3,
            area / 1e2,
            gradient / mmhg,
        );
        assert!(cycle(k, "opening_time") < cycle(k, "closing_time"), "cycle {k} opens, then closes (in contact)");
        assert!(leak.abs() < 0.01 * forward, "cycle {k}: leak {leak} of forward {forward}");
        if k == 3 {
            assert!((60e3..=75e3).contains(&forward), "stroke volume {forward} mm^3 outside 60-75 ml");
            assert!((1.0e3..=1.7e3).contains(&jet), "peak jet {jet} mm/s outside 1.0-1.7 m/s");
            assert!((250.0..=400.0).contains(&area), "open area {area} mm^2 outside 2.5-4 cm^2");
            assert!(gradient > 0.0 && gradient < 10.0 * mmhg, "mean systolic gradient {gradient} Pa outside (0, 10) mmHg");
        }
    }
    let (second, third) = (cycle(2, "forward_volume"), cycle(3, "forward_volume"));
    println!("valve-3d-sector: forward volume of cycle 3 against cycle 2: {:+.3} %", 100.0 * (third / second - 1.0));
    assert!((third - second).abs() < 0.02 * second, "forward volumes {second} and {third}");
}

/// cases/valve-2d.toml over its three cardiac cycles (see its header), the checks: every
/// step done (3.5 beats: the cycles run from mid-diastole, t = 0.4 + 0.8 (K - 1), so that each
/// holds one opening and one closing); the valve opens and closes in every cycle; the leak
/// (backward flow through the valve while its tip touches the line) below 1 % of the forward
/// volume in every cycle; the forward volume of cycle 3 within 2 % of cycle 2's; the aortic
/// pressure in cycle 3 within 70-125 mmHg; and this run's figures (fdfsi's, session 31, blood with SUPG: a
/// regression, not a reference) to the precision the header gives. With `FDFSI_LONG_RUNS` (see
/// [`long_run`]) a finished run is checked without running again.
#[test]
#[ignore = "about 46 minutes; run with --ignored"]
fn valve_2d_closes_and_opens_over_three_cardiac_cycles() {
    let out = long_run("valve-2d");
    let s = summary_json(&out);
    assert_eq!(s["steps"].as_u64(), Some(2800), "every step done");
    let q = |name: &str| s["quantities"][name].as_f64().unwrap_or(f64::NAN);
    let cycle = |k: usize, name: &str| q(&format!("cycle_{k}_{name}"));
    for k in 1..=3 {
        let (forward, leak) = (cycle(k, "forward_volume"), cycle(k, "leak_volume"));
        println!(
            "valve-2d cycle {k}: forward {forward:.1} mm^2, backward {:.1}, leak {leak:.3e}; opens at {:.3} s, closes at {:.3} s \
             (from mid-diastole); peak jet {:.1} mm/s, peak flux {:.1} mm^2/s, peak gradient {:.1} Pa",
            cycle(k, "backward_volume"),
            cycle(k, "opening_time"),
            cycle(k, "closing_time"),
            cycle(k, "peak_max_speed"),
            cycle(k, "peak_valve_flux"),
            cycle(k, "peak_transvalvular_gradient"),
        );
        assert!(cycle(k, "opening_time") < cycle(k, "closing_time"), "cycle {k} opens, then closes");
        assert!(leak.abs() < 0.01 * forward, "cycle {k}: leak {leak} of forward {forward}");
    }
    let (second, third) = (cycle(2, "forward_volume"), cycle(3, "forward_volume"));
    println!("valve-2d: forward volume of cycle 3 against cycle 2: {:+.3} %", 100.0 * (third / second - 1.0));
    assert!((third - second).abs() < 0.02 * second, "forward volumes {second} and {third}");
    let h = history_columns(&out);
    let mmhg = 133.322;
    let aortic: Vec<f64> = h["time"].iter().zip(&h["p_ao"]).filter(|(t, _)| **t > 2.0).map(|(_, p)| p / mmhg).collect();
    let (lo, hi) = aortic.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    println!("valve-2d cycle 3: aortic pressure {lo:.1} to {hi:.1} mmHg");
    assert!(lo > 70.0 && hi < 125.0, "aortic pressure {lo} to {hi} mmHg");
    // This run's figures (fdfsi, session 31, the build of 6aaf537; the case header): a regression.
    let near = |name: &str, expected: f64, rel: f64| {
        let v = cycle(3, name);
        assert!((v - expected).abs() <= rel * expected.abs(), "cycle 3 {name}: {v} against {expected}");
    };
    near("forward_volume", 1273.7, 5e-3);
    near("backward_volume", 88.24, 5e-3);
    near("peak_max_speed", 2878.7, 0.02);
    near("peak_valve_flux", 9928.6, 0.02);
    near("peak_transvalvular_gradient", 1624.0, 0.02);
    assert!((cycle(3, "opening_time") - 0.383).abs() <= 0.002 && (cycle(3, "closing_time") - 0.698).abs() <= 0.002);
}
