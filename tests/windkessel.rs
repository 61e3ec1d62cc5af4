//! The three-element Windkessel (RCR) outlet (issue 17), coupled implicitly: its flux `Q` and
//! capacitor pressure `P_c` are unknowns of the flow system. On a rigid channel with a given
//! inflow the outlet flux is the inflow (mass conservation), so the outlet pressure is the RCR
//! ordinary differential equation's, `C dP_c/dt = Q - (P_c - P_d)/R_d`, `P = R_p Q + P_c`:
//! - to round-off against that equation stepped by the run's own scheme (implicit Euler, BDF2
//!   after an Euler step), with the direct and the augmented-Lagrangian solvers;
//! - to 1e-6 relative against its closed-form solution for `Q = sin(2 pi t)` (BDF2, dt = 1/5000),
//!   at second order in dt;
//! - steady: `P = (R_p + R_d) Q + P_d`; axisymmetric: `Q` over the whole circumference.

use fdfsi::case::Case;
use fdfsi::run::{run_case, RunOptions, RunSummary};
use std::f64::consts::PI;
use std::path::Path;

const RP: f64 = 0.5;
const C: f64 = 0.2;
const RD: f64 = 2.0;

/// The channel `[0, 4] x [0, 1]` (plane) with the parabolic inflow `6 y (1 - y) sin(2 pi t)` (flux
/// `sin(2 pi t)`), Stokes, the RCR outlet (`P_d`, `P_c(0)` as given), `steps` steps of `dt`.
fn channel(scheme: &str, method: &str, dt: f64, steps: usize, distal: f64, initial: f64) -> String {
    format!(
        r#"title = "Windkessel channel"
[mesh]
kind = "channel"
length = 4.0
height = 1.0
n = [4, 2]
[physics]
formulation = "plane"
[fluid]
density = 1.0
viscosity = 0.1
[[boundary]]
name = "inlet"
type = "velocity"
value = ["6*y*(1-y)", 0.0]
time_function = {{ kind = "sine", period = 1.0 }}
[[boundary]]
name = "bottom"
type = "no-slip"
[[boundary]]
name = "top"
type = "no-slip"
[[boundary]]
name = "outlet"
type = "windkessel"
windkessel = {{ proximal_resistance = {RP}, compliance = {C}, distal_resistance = {RD}, distal_pressure = {distal}, initial_pressure = {initial} }}
[time]
dt = {dt:e}
end = {end:e}
scheme = "{scheme}"
output_every = 100000
[solver.linear]
method = "{method}"
"#,
        end = dt * steps as f64
    )
}

fn run(text: &str) -> (RunSummary, Vec<Vec<f64>>, Vec<String>) {
    let case = Case::from_toml_str(text, "windkessel.toml").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let summary = run_case(&case, &RunOptions::new(&out, Path::new(".")), &mut |_: &str| {}).unwrap();
    let csv = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    (summary, rows, header)
}

fn column(header: &[String], name: &str) -> usize {
    header.iter().position(|c| c == name).unwrap_or_else(|| panic!("no column {name} in {header:?}"))
}

/// The RCR equation stepped as the run steps it: implicit Euler, or BDF2 after a first Euler
/// step (constant dt); `(t, Q, P)` per step from `P_c(0)`.
fn stepped_ode(bdf2: bool, dt: f64, steps: usize, distal: f64, initial: f64) -> Vec<(f64, f64, f64)> {
    let mut pc = vec![initial];
    let mut out = vec![(0.0, 0.0, initial)];
    for n in 1..=steps {
        let t = n as f64 * dt;
        let q = (2.0 * PI * t).sin();
        // C (a0 P - hist) / dt = Q - (P - P_d) / R_d.
        let (a0, hist) = if bdf2 && n > 1 { (1.5, 2.0 * pc[n - 1] - 0.5 * pc[n - 2]) } else { (1.0, pc[n - 1]) };
        let p = (C * hist / dt + q + distal / RD) / (C * a0 / dt + 1.0 / RD);
        pc.push(p);
        out.push((t, q, RP * q + p));
    }
    out
}

#[test]
fn the_outlet_follows_the_rcr_equation_stepped_alike_to_round_off() {
    let (distal, initial) = (0.3, 1.1);
    for (scheme, method) in [("euler", "direct"), ("bdf2", "direct"), ("bdf2", "augmented-lagrangian")] {
        let (summary, rows, header) = run(&channel(scheme, method, 0.01, 100, distal, initial));
        let (q, p, pc) = (column(&header, "outlet_flux"), column(&header, "outlet_pressure"), column(&header, "outlet_capacitor_pressure"));
        let ode = stepped_ode(scheme == "bdf2", 0.01, 100, distal, initial);
        assert_eq!(rows.len(), ode.len());
        let (mut eq, mut ep) = (0.0f64, 0.0f64);
        for (row, (t, q_ode, p_ode)) in rows.iter().zip(&ode) {
            assert!((row[1] - t).abs() < 1e-12);
            eq = eq.max((row[q] - q_ode).abs());
            ep = ep.max((row[p] - p_ode).abs());
            assert!((row[p] - (RP * row[q] + row[pc])).abs() < 1e-14);
        }
        println!("{scheme} {method}: max |Q - Q_in| = {eq:.2e}, max |P - P_ode| = {ep:.2e}");
        // Measured at most 8e-15 (the augmented-Lagrangian solver's too).
        assert!(eq < 1e-12 && ep < 1e-12, "{scheme} {method}: {eq:e} {ep:e}");
        // Q and P_c: two unknowns of the system.
        assert_eq!(summary.dofs.get("windkessel"), Some(&2), "{:?}", summary.dofs);
    }
}

/// `P_c` of `C dP_c/dt = sin(w t) - P_c / R_d` from `P_c(0) = 0`.
fn exact_capacitor_pressure(t: f64) -> f64 {
    let (w, tau) = (2.0 * PI, RD * C);
    let a = RD / (1.0 + (w * tau).powi(2));
    a * ((w * t).sin() - w * tau * (w * t).cos() + w * tau * (-t / tau).exp())
}

#[test]
fn the_outlet_pressure_matches_the_rcr_solution_to_1e_6() {
    let mut errors = Vec::new();
    for steps in [2500, 5000] {
        let dt = 1.0 / steps as f64;
        let (_, rows, header) = run(&channel("bdf2", "direct", dt, steps, 0.0, 0.0));
        let p = column(&header, "outlet_pressure");
        let (mut err, mut scale) = (0.0f64, 0.0f64);
        for row in &rows {
            let t = row[1];
            let exact = RP * (2.0 * PI * t).sin() + exact_capacitor_pressure(t);
            err = err.max((row[p] - exact).abs());
            scale = scale.max(exact.abs());
        }
        println!("dt = 1/{steps}: max |P - P_exact| / max |P_exact| = {:.3e}", err / scale);
        errors.push(err / scale);
    }
    let rate = (errors[0] / errors[1]).log2();
    println!("rate {rate:.3}");
    assert!(errors[1] < 1e-6, "{errors:?}");
    assert!(rate > 1.9, "rate {rate}");
}

/// Steady: `dP_c/dt = 0`, so `P_c = P_d + R_d Q` and `P = (R_p + R_d) Q + P_d`; plane (`Q` per
/// unit depth, the parabolic inflow's 1) and axisymmetric (the pipe `(z, r)` in `[0, 4] x [0, 1]`
/// with the inflow `2 (1 - r^2)`: `Q = 2 pi int_0^1 2 (1 - r^2) r dr = pi`).
#[test]
fn a_steady_outlet_is_the_two_resistances_in_series() {
    let distal = 0.3;
    for (formulation, inflow, axis, flux) in [("plane", "6*y*(1-y)", "no-slip", 1.0), ("axisymmetric", "2*(1-y^2)", "axis", PI)] {
        let text = format!(
            r#"title = "steady Windkessel"
[mesh]
kind = "rectangle"
x = [0.0, 4.0]
y = [0.0, 1.0]
n = [6, 3]
[physics]
formulation = "{formulation}"
model = "navier-stokes"
[fluid]
density = 1.0
viscosity = 0.1
[[boundary]]
name = "left"
type = "velocity"
value = ["{inflow}", 0.0]
[[boundary]]
name = "bottom"
type = "{axis}"
[[boundary]]
name = "top"
type = "no-slip"
[[boundary]]
name = "right"
type = "windkessel"
windkessel = {{ proximal_resistance = {RP}, compliance = {C}, distal_resistance = {RD}, distal_pressure = {distal} }}
"#
        );
        let (summary, _, _) = run(&text);
        let q = summary.quantities["right_flux"];
        let p = summary.quantities["right_pressure"];
        let pc = summary.quantities["right_capacitor_pressure"];
        println!("{formulation}: Q = {q:.15}, P = {p:.15}, P_c = {pc:.15}");
        assert!((q - flux).abs() < 1e-12 * flux, "{formulation}: Q = {q}, expected {flux}");
        assert!((pc - (distal + RD * q)).abs() < 1e-12 && (p - (distal + (RP + RD) * q)).abs() < 1e-12, "{formulation}: P = {p}, P_c = {pc}");
    }
}

/// In an FSI run the outlet's unknowns are in the monolithic FSI system (block `windkessel`) and
/// carried from step to step across the adapted meshes: model problem 2 (the skewed plate,
/// implicit Euler, dt = 1, the inflow ramped over t = 2) with its outlet a Windkessel. The fluid
/// the plate covers is kept, so the outlet flux is the inflow's; the outlet pressure is the RCR
/// equation stepped with the run's flux, to round-off.
#[test]
fn an_fsi_run_carries_its_outlet_in_the_monolithic_system() {
    let cases = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let text = std::fs::read_to_string(cases.join("model-problem-2.toml")).unwrap();
    let (distal, initial) = (0.1, 0.4);
    let outlet = format!(
        "name = \"right\"\ntype = \"windkessel\"\nwindkessel = {{ proximal_resistance = {RP}, compliance = {C}, distal_resistance = {RD}, distal_pressure = {distal}, initial_pressure = {initial} }}"
    );
    let text = text.replace("end = 12.0", "end = 4.0").replace("n = [64, 16]", "n = [32, 8]").replace("name = \"right\"\ntype = \"free\"", &outlet);
    assert!(text.contains("windkessel") && text.contains("end = 4.0"));
    let mut fluid_dofs = Vec::new();
    for method in ["direct", "augmented-lagrangian"] {
        fluid_dofs.push(fsi_outlet_follows_the_rcr_equation(&format!("{text}\n[solver.linear]\nmethod = \"{method}\"\n"), &cases, distal, initial));
    }
    // Q and P_c are two unknowns of the fluid's part of the system.
    let plain = Case::from_toml_str(&text.replace(&outlet, "name = \"right\"\ntype = \"free\""), "mp2.toml").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let summary = run_case(&plain, &RunOptions::new(dir.path().join("out"), &cases), &mut |_: &str| {}).unwrap();
    assert_eq!(fluid_dofs, vec![summary.dofs["fluid"] + 2; 2]);
}

/// Runs the case `text` and checks its outlet against the RCR equation; returns its fluid
/// unknowns.
fn fsi_outlet_follows_the_rcr_equation(text: &str, cases: &Path, distal: f64, initial: f64) -> usize {
    let case = Case::from_toml_str(text, "mp2-windkessel.toml").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let summary = run_case(&case, &RunOptions::new(&out, cases), &mut |_: &str| {}).unwrap();
    let csv = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    let (q, p, inflow) = (column(&header, "right_flux"), column(&header, "right_pressure"), column(&header, "inlet_flux"));
    let dt = 1.0;
    let mut pc = initial;
    for row in &rows {
        // C (P_c - P_c^n) / dt = Q - (P_c - P_d) / R_d.
        pc = (C * pc / dt + row[q] + distal / RD) / (C / dt + 1.0 / RD);
        println!("t = {}: Q = {:.12}, inflow {:.12}, P = {:.12}, P_ode = {:.12}", row[1], row[q], row[inflow], row[p], RP * row[q] + pc);
        // `inlet_flux` is outward.
        assert!((row[q] + row[inflow]).abs() < 1e-10, "Q = {} vs inflow {}", row[q], -row[inflow]);
        assert!((row[p] - (RP * row[q] + pc)).abs() < 1e-10, "P = {}", row[p]);
    }
    assert_eq!(rows.len(), 4);
    assert!(rows[3][q] > 0.99, "the inflow is on: {}", rows[3][q]);
    summary.dofs["fluid"]
}
