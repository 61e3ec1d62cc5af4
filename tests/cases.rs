//! Every case in `cases/` runs and reproduces its documented check (see each file's header).

use fdfsi::case::Case;
use fdfsi::checkpoint::Checkpoint;
use fdfsi::run::{run_case, RunOptions, RunSummary, BUILTIN_CASES};
use fdfsi::fem::vtk::{read_pvd, read_vtu};
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
    let out = std::env::temp_dir().join(format!("fdfsi-test-{name}-{}", std::process::id()));
    let summary = run_case(&case, &RunOptions::new(out.clone(), dir), &mut |_: &str| {}).unwrap();
    (summary, out)
}

/// `out/summary.json`, parsed.
fn summary_json(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
}

fn q(s: &RunSummary, name: &str) -> f64 {
    *s.quantities.get(name).unwrap_or_else(|| panic!("quantity {name} missing"))
}

#[test]
fn every_case_file_is_a_builtin_and_is_tested() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok()?.path().file_stem()?.to_str().map(String::from))
        .collect();
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
    assert_eq!(s.symbolic_factorizations, 1);
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
    let case_text = std::fs::read_to_string(out.join("case.toml")).unwrap();
    assert_eq!(p["case_sha256"].as_str(), Some(fdfsi::provenance::sha256_hex(case_text.as_bytes()).as_str()));
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
}

#[test]
fn quarter_pipe_3d_conserves_mass() {
    let (s, _) = run("quarter-pipe-3d-stokes");
    let (qin, qout) = (q(&s, "inlet_flux"), q(&s, "outlet_flux"));
    assert!((qin + qout).abs() < 1e-11 * qin.abs(), "{qin} vs {qout}");
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
    let rel = |name: &str, reference: f64| (q(&s, name) - reference).abs() / reference.abs();
    // Tolerances of the benchmark issue: drag 0.1 %, lift 2 %, pressure difference 0.5 %.
    assert!(rel("drag_coefficient", 5.57953523384) < 1e-3, "drag {}", q(&s, "drag_coefficient"));
    assert!(rel("lift_coefficient", 0.010618948146) < 2e-2, "lift {}", q(&s, "lift_coefficient"));
    assert!(rel("pressure_difference", 0.11752016697) < 5e-3, "dp {}", q(&s, "pressure_difference"));
    // Newton converges quadratically: the last residual drops far below the square of the one
    // before it times a modest constant.
    let r = &s.residual_norms;
    assert!(r.len() >= 3 && r.len() <= 8, "{r:?}");
    let (a, b) = (r[r.len() - 3], r[r.len() - 2]);
    assert!(b < 1e-2 * a, "{r:?}");
    assert_eq!(s.symbolic_factorizations, 1, "one symbolic factorisation per mesh");
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
    assert!(worst < 0.01, "{worst}");
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
    let a = fdfsi::run::adapt_case(&case, &dir, &out).unwrap();
    assert!(a.gamma_f_measure <= a.gamma_s_measure * (1.0 + 1e-12));
    assert!(a.gamma_f_measure > 0.8 * a.gamma_s_measure, "{a:?}");
    assert_eq!(a.stats.coupling_facets, read_vtu(&out.join("gamma_f.vtu")).unwrap().num_cells());
    assert_eq!(a.adapted_cells, read_vtu(&out.join("adapted.vtu")).unwrap().num_cells());
    assert_eq!(read_vtu(&out.join("gamma_s.vtu")).unwrap().num_cells(), a.gamma_s_pieces);
    assert!(a.stats.min_quality > 0.0);
}

#[test]
fn cylinder_re100_starts_up_cleanly() {
    // The full run (t = 8, 800 steps) takes tens of minutes and is reported in BENCHMARKS.md;
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
fn cook_membrane_tip_displacement_is_near_the_published_value() {
    let (s, out) = run("cook-membrane");
    // Published converged values are about 6.9 mm (EXACT-SOLUTIONS.md 1.6); Q2/P1disc does not
    // lock, so 8 x 8 cells are within 1.5 %.
    let tip = q(&s, "tip_displacement_y");
    assert!((tip - 6.9).abs() < 0.1, "{tip}");
    let entries = read_pvd(&out.join("solution.pvd")).unwrap();
    assert_eq!(entries[0].name, "solid");
    let grid = read_vtu(&entries[0].resolve(&out.join("solution.pvd"))).unwrap();
    assert_eq!(grid.cell_array("cauchy_stress").unwrap().values.len(), 9 * s.cells);
    assert!(grid.point_array("displacement").is_some());
}

#[test]
fn axisymmetric_cylinder_inflates_to_the_exact_radius() {
    let (s, out) = run("cylinder-inflation-axisymmetric");
    // EXACT-SOLUTIONS.md 1.4: P_i = 0.21541965495917 G inflates A = 1 to a = 1.3.
    let u = q(&s, "inner_radial_displacement");
    assert!((u - 0.3).abs() < 1e-5, "{u}");
    // One history row per load increment, the probe growing with the load.
    let history = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let rows: Vec<Vec<f64>> = history.lines().skip(1).map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    assert_eq!(rows.len(), 4);
    assert!(rows.windows(2).all(|w| w[1][4] > w[0][4] && w[1][1] > w[0][1]), "{rows:?}");
    assert!((rows[3][4] - u).abs() < 1e-14);
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
    assert!(diff < 0.01, "{diff}");
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

/// Model problem 1 checks on a history: flux in = flux out every step, and the slab moved.
fn check_model_problem_1(out: &Path, steps: usize) -> std::collections::BTreeMap<String, Vec<f64>> {
    let h = history_columns(out);
    assert_eq!(h["step"].len(), steps);
    for (k, (i, o)) in h["inlet_flux"].iter().zip(&h["outlet_flux"]).enumerate() {
        assert!((i + o).abs() < 1e-10, "step {}: flux in {i}, out {o}", k + 1);
    }
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

/// The whole case (4.5 periods; about 10 minutes): no failed step, a large motion, and the tip
/// path of the last full period repeats the one before within 2 % (L2 over the period).
#[test]
#[ignore = "about 10 minutes; run with --ignored"]
fn model_problem_1_motion_is_periodic() {
    let (s, out) = run("model-problem-1");
    assert_eq!(s.steps, 360);
    let h = check_model_problem_1(&out, 360);
    let (x, y) = (&h["tip_displacement_x"], &h["tip_displacement_y"]);
    let period = 80;
    let max_x = x.iter().fold(0.0f64, |m, v| m.max(*v));
    let max_y = y.iter().fold(0.0f64, |m, v| m.max(*v));
    assert!(max_x > 0.25 && max_y > 0.08, "large rotation: tip moves ({max_x}, {max_y})");
    let (a, b) = (2 * period, 3 * period); // periods 3 and 4
    let num: f64 = (0..period).map(|i| (x[a + i] - x[b + i]).powi(2) + (y[a + i] - y[b + i]).powi(2)).sum();
    let den: f64 = (0..period).map(|i| x[b + i].powi(2) + y[b + i].powi(2)).sum();
    let repeat = (num / den).sqrt();
    println!("model problem 1: tip path of period 4 vs period 3: {repeat:.4} (L2, relative)");
    assert!(repeat < 0.02, "{repeat}");
}

/// The values of a profile CSV (last column).
fn profile_values(out: &Path, name: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(out.join(format!("profiles/{name}.csv"))).unwrap();
    text.lines().skip(1).map(|l| l.rsplit(',').next().unwrap().parse().unwrap()).collect()
}

/// Model problems 3 and 4 at equilibrium: the upstream pressure is the applied traction and the
/// downstream one zero (within 1 % of it), the fluid is at rest (speed below 1e-3 of its peak)
/// and the pressure jumps exactly on gamma_f: the cells on either side of it hold their side's
/// pressure within 1 % (no smearing). The multiplier, the traction on the membrane, is `p n` (`n`
/// the facet normal, its `axial` component positive) within 5 % of `p` at every vertex of every
/// gamma_f facet. Returns the history.
fn check_membrane_equilibrium(out: &Path, axial: usize) -> std::collections::BTreeMap<String, Vec<f64>> {
    let h = history_columns(out);
    let summary = summary_json(out);
    let q = |name: &str| summary["quantities"][name].as_f64().unwrap_or_else(|| panic!("quantity {name} missing"));
    let applied = q("applied_traction");
    assert!((applied - 1.0).abs() < 1e-12, "the traction is held at 1 after the rise: {applied}");
    let (up, down) = (q("upstream_pressure"), q("downstream_pressure"));
    println!("equilibrium: upstream pressure {up:.8}, downstream {down:.3e}, applied {applied}");
    assert!((up - applied).abs() < 0.01 * applied, "upstream pressure {up}");
    assert!(down.abs() < 0.01 * applied, "downstream pressure {down}");
    let speed = &h["max_fluid_speed"];
    let peak = speed.iter().fold(0.0f64, |m, v| m.max(*v));
    let last = *speed.last().unwrap();
    println!("max fluid speed: peak {peak:.4e}, last {last:.4e} ({:.2e} of the peak)", last / peak);
    assert!(peak > 0.01 && last < 1e-3 * peak, "speed {last} of peak {peak}");
    for (side, value) in [("pressure_upstream_side", applied), ("pressure_downstream_side", 0.0)] {
        let p = profile_values(out, side);
        assert!(p.len() > 10, "{side}: {} points", p.len());
        let worst = p.iter().map(|v| (v - value).abs()).fold(0.0f64, f64::max);
        println!("{side}: {} points, max |p - {value}| = {worst:.3e}", p.len());
        assert!(worst < 0.01 * applied, "{side}: pressure smeared across gamma_f by {worst}");
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
    assert!(dev < 0.05 * applied, "the traction on gamma_f is not p n: {dev}");
    h
}

#[test]
fn model_problem_3_reaches_equilibrium_with_the_pressure_jump_on_gamma_f() {
    let (s, out) = run("model-problem-3");
    assert_eq!(s.steps, 60);
    let h = check_membrane_equilibrium(&out, 0);
    // Overdamped: the membrane bulges downstream monotonically (to round-off at the end).
    let w = &h["centre_displacement"];
    assert!(w.windows(2).all(|p| p[1] > p[0] - 1e-9), "{w:?}");
    assert!(*w.last().unwrap() > 0.05, "centre displacement {}", w.last().unwrap());
    assert!(out.join("plots/centre_displacement.png").exists());
}

#[test]
fn model_problem_4_coarse_first_steps_seal_the_pipe_and_bulge_the_membrane() {
    // CI runs the first 5 steps on a coarser mesh (468 tetrahedra, 30 hexahedra); the full case
    // is model_problem_4_follows_model_problem_3 below.
    use fdfsi::case::{MeshSpec, SolidMeshSpec};
    let (s, out) = run_with("model-problem-4", |c| {
        c.mesh = Some(MeshSpec::Pipe { radius: 1.0, length: 4.0, n_radial: 4, n_axial: 6, quarter: true });
        let solid = c.solid.as_mut().unwrap();
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
}

#[test]
fn model_problem_4_fine_mesh_seals_the_pipe_at_rest() {
    // The run takes about an hour (model_problem_4_follows_model_problem_3 below); CI checks
    // the case: meshes, the adaptation at t = 0, the dofs.
    let (case, dir) = case_file("model-problem-4-fine");
    let summary = fdfsi::check::check(&case, "model-problem-4-fine.toml", &dir).unwrap();
    assert!(summary.description.contains("4662 cells") && summary.description.contains("189 cells"), "{}", summary.description);
    // gamma_f crosses the layer of cells between z = 12/7 and 16/7: each of its 3 x 222
    // tetrahedra is cut in a triangle or a quadrilateral (two facets), so 666 to 1332 facets; the
    // adaptation makes 888 (a regression count).
    let facets: usize = summary.description.split(" coupling elements").next().and_then(|t| t.rsplit(' ').next()).and_then(|n| n.parse().ok()).unwrap();
    assert!((666..=1332).contains(&facets), "{}", summary.description);
    assert_eq!(facets, 888, "{}", summary.description);
    assert_eq!(summary.steps, 60);
    // gamma_f covers gamma_s up to the wall: the flat membrane face is the quarter of the
    // 72-gon, area (pi/4) (72 / (2 pi)) sin(2 pi / 72) = 0.784398. (The membrane's rim points
    // between the wall's vertices lie off the wall's planes by round-off; before the cut test
    // allowed for that, wall edges through the rim were missed and gamma_f had holes along the
    // rim: 873 facets.)
    let out = tempfile::tempdir().unwrap();
    let a = fdfsi::run::adapt_case(&case, &dir, out.path()).unwrap();
    let polygon = std::f64::consts::FRAC_PI_4 * 72.0 / (2.0 * std::f64::consts::PI) * (2.0 * std::f64::consts::PI / 72.0).sin();
    assert!((a.gamma_s_measure - polygon).abs() < 1e-12, "gamma_s {}", a.gamma_s_measure);
    assert!((a.gamma_f_measure - a.gamma_s_measure).abs() < 1e-12, "gamma_f {} vs gamma_s {}", a.gamma_f_measure, a.gamma_s_measure);
}

fn case_file(name: &str) -> (Case, PathBuf) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    (Case::read(&dir.join(format!("{name}.toml"))).unwrap(), dir)
}

/// The output folder of a long case run. With `FDFSI_LONG_RUNS=DIR` the case runs into
/// `DIR/NAME` with a checkpoint every step, resumes there if a checkpoint is there, and is not run
/// again if a finished run is there (its `summary.json`; its `case.toml` must be the case's up to
/// `[solver.linear]`, which changes only round-off), so runs made with
/// `fdfsi run CASE --out DIR/NAME` are checked without running again.
fn long_run(name: &str) -> PathBuf {
    let Some(dir) = std::env::var_os("FDFSI_LONG_RUNS") else { return run(name).1 };
    let out = PathBuf::from(dir).join(name);
    let (case, cases) = case_file(name);
    if out.join("summary.json").exists() {
        let mut used = Case::from_toml_str(&std::fs::read_to_string(out.join("case.toml")).unwrap(), "case.toml").unwrap();
        used.solver.linear = case.solver.linear.clone();
        assert_eq!(used.to_toml(), case.to_toml(), "{} was run with another case than cases/{name}.toml", out.display());
        return out;
    }
    let (case, options) = if Checkpoint::path(&out).exists() { RunOptions::resume(&out).unwrap() } else { (case, RunOptions::new(out.clone(), cases)) };
    run_case(&case, &RunOptions { checkpoint_every: Some(1), ..options }, &mut |_: &str| {}).unwrap();
    out
}

/// The centre displacement of model problem 4 follows model problem 3 on the fine 3D mesh (5 %
/// of the final value over the whole transient), and the equilibrium positions of the two 3D
/// meshes converge towards the axisymmetric one. About three hours: run with --ignored (and
/// `FDFSI_LONG_RUNS`, see [`long_run`], to check finished runs).
#[test]
#[ignore = "about three hours; run with --ignored"]
fn model_problem_4_follows_model_problem_3() {
    let out3 = long_run("model-problem-3");
    let out4 = long_run("model-problem-4");
    let out4f = long_run("model-problem-4-fine");
    let w3 = history_columns(&out3)["centre_displacement"].clone();
    for out in [&out4, &out4f] {
        assert_eq!(history_columns(out)["time"].len(), 60, "{}: 60 steps", out.display());
        check_membrane_equilibrium(out, 2);
    }
    let w4 = history_columns(&out4)["centre_displacement"].clone();
    let w4f = history_columns(&out4f)["centre_displacement"].clone();
    let scale = *w3.last().unwrap();
    let worst = |w: &[f64]| w.iter().zip(&w3).map(|(a, b)| (a - b).abs()).fold(0.0f64, f64::max) / scale;
    let (gap, gap_fine) = ((w4.last().unwrap() - scale).abs() / scale, (w4f.last().unwrap() - scale).abs() / scale);
    println!(
        "centre displacement: axisymmetric {scale:.5}, 3D {:.5} (gap {gap:.4}, transient {:.4}), 3D fine {:.5} (gap {gap_fine:.4}, transient {:.4})",
        w4.last().unwrap(),
        worst(&w4),
        w4f.last().unwrap(),
        worst(&w4f)
    );
    assert!(worst(&w4f) < 0.05, "fine 3D mesh vs axisymmetric over the transient: {}", worst(&w4f));
    assert!(gap_fine < gap, "refinement closes the equilibrium gap: {gap} -> {gap_fine}");
}
