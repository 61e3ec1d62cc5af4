//! Several solids in one case (`[[solid]]` tables; issue 17): their meshes are joined into one
//! solid of several bodies, each with its own material, density, body force and boundary
//! conditions. Bodies that do not touch do not interact, so each must move as it does alone:
//! a run of two solids is checked against the runs of each alone, quasi-static and dynamic.

use fdfsi::case::Case;
use fdfsi::fem::vtk::{read_pvd, read_vtu};
use fdfsi::run::{run_case, RunOptions, RunSummary};
use std::path::{Path, PathBuf};

/// Runs the case `text` in a fresh folder named after `name`.
fn run(name: &str, text: &str) -> (RunSummary, PathBuf) {
    let case = Case::from_toml_str(text, &format!("{name}.toml")).unwrap_or_else(|e| panic!("{name}: {e}"));
    let out = std::env::temp_dir().join(format!("fdfsi-several-solids-{name}-{}", std::process::id()));
    let summary = run_case(&case, &RunOptions::new(out.clone(), Path::new(env!("CARGO_MANIFEST_DIR")).join("cases")), &mut |_: &str| {})
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    (summary, out)
}

/// A plane case of the solids `solids` (their tables, `SOLID` for `solid`: one `[solid]` table,
/// or several `[[solid]]`), `physics` (more keys of `[physics]`) and `rest` (the other tables).
fn case_of(title: &str, physics: &str, solids: &[&str], rest: &str) -> String {
    let header = if solids.len() > 1 { "[[solid]]" } else { "[solid]" };
    let tables: Vec<String> = solids.iter().map(|s| s.replace("[SOLID]", header).replace("SOLID", "solid")).collect();
    format!("title = \"{title}\"\n\n[physics]\nformulation = \"plane\"\n{physics}\n{}\n{rest}", tables.join("\n"))
}

/// The relative difference of quantity `name` in two runs.
fn difference(a: &RunSummary, b: &RunSummary, name: &str) -> f64 {
    let (x, y) = (a.quantities[name], b.quantities[name]);
    println!("{name}: {x:.15e} together, {y:.15e} alone");
    (x - y).abs() / y.abs()
}

/// Cook's membrane (nearly incompressible neo-Hookean) beside a fibre-reinforced incompressible
/// bar under a dead and a follower load: together as two `[[solid]]` tables, each tip moves as
/// in the run of its solid alone, to 1e-12 relative (the two solve one system together: their
/// Newton iterations stop together).
#[test]
fn two_quasi_static_solids_move_as_each_alone() {
    let cook = r#"[SOLID]
name = "cook"
mesh = { kind = "quadrilateral", corners = [[0.0, 0.0], [48.0, 44.0], [48.0, 60.0], [0.0, 44.0]], n = [8, 8] }
model = "neo-hookean"
shear_modulus = 80.1938
bulk_modulus = 400942.0
loading = { steps = 2, mode = "updated" }

[[SOLID.boundary]]
name = "left"
type = "displacement"
value = [0.0, 0.0]

[[SOLID.boundary]]
name = "right"
type = "traction"
value = [0.0, 6.25]
"#;
    let bar = r#"[SOLID]
name = "bar"
mesh = { kind = "rectangle", x = [60.0, 100.0], y = [0.0, 4.0], n = [10, 2] }
model = "neo-hookean"
shear_modulus = 100.0
fibres = { k1 = 50.0, k2 = 2.0, direction = [1.0, 0.3] }
loading = { steps = 2, mode = "updated" }

[[SOLID.boundary]]
name = "left"
type = "displacement"
value = [0.0, 0.0]

[[SOLID.boundary]]
name = "right"
type = "traction"
value = [0.0, 0.05]

[[SOLID.boundary]]
name = "top"
type = "pressure"
value = [0.01]
"#;
    let probes = |which: &[&str]| -> String {
        let mut text = String::new();
        for (name, point) in [("cook_tip_y", "[48.0, 60.0]"), ("bar_tip_y", "[100.0, 4.0]")] {
            if which.iter().any(|w| name.starts_with(w)) {
                text += &format!("[[output.probe]]\nname = \"{name}\"\nfield = \"displacement\"\ncomponent = 1\npoint = {point}\n\n");
            }
        }
        text
    };
    let (both, out) = run("two", &case_of("two solids", "", &[cook, bar], &probes(&["cook", "bar"])));
    let (cook_alone, _) = run("cook", &case_of("cook alone", "", &[cook], &probes(&["cook"])));
    let (bar_alone, _) = run("bar", &case_of("bar alone", "", &[bar], &probes(&["bar"])));
    // Measured: cook 0, bar 7e-14.
    assert!(difference(&both, &cook_alone, "cook_tip_y") < 1e-12);
    assert!(difference(&both, &bar_alone, "bar_tip_y") < 1e-12);
    assert!(both.quantities["cook_tip_y"] > 1.0 && both.quantities["bar_tip_y"] > 0.1, "both solids move");
    assert_eq!(both.dofs["solid"], cook_alone.dofs["solid"] + bar_alone.dofs["solid"]);
    // The solid output marks each cell's body, and `case.toml` keeps both tables.
    let entries = read_pvd(&out.join("solution.pvd")).unwrap();
    let grid = read_vtu(&entries.last().unwrap().resolve(&out.join("solution.pvd"))).unwrap();
    let body = grid.cell_data.iter().find(|a| a.name == "body").expect("cell data `body`");
    assert_eq!(body.values.iter().filter(|&&b| b == 0.0).count(), 64);
    assert_eq!(body.values.iter().filter(|&&b| b == 1.0).count(), 20);
    let written = Case::read(&out.join("case.toml")).unwrap();
    assert_eq!(written.solid.iter().map(|s| s.name.clone().unwrap_or_default()).collect::<Vec<_>>(), ["cook", "bar"]);
}

/// Two bars falling under gravity from rest (dynamic, BDF2), of other densities, gravities and
/// stiffnesses: together as two `[[solid]]` tables, each tip moves as in the run of its bar
/// alone at every step, to 1e-12 relative (measured: identical).
#[test]
fn two_dynamic_solids_move_as_each_alone() {
    let heavy = r#"[SOLID]
name = "heavy"
mesh = { kind = "rectangle", x = [0.0, 0.35], y = [0.0, 0.02], n = [8, 1] }
model = "saint-venant-kirchhoff"
shear_modulus = 0.5e6
poissons_ratio = 0.4
density = 1000.0
body_force = [0.0, -2000.0]

[[SOLID.boundary]]
name = "left"
type = "displacement"
value = [0.0, 0.0]
"#;
    let light = r#"[SOLID]
name = "light"
mesh = { kind = "rectangle", x = [0.0, 0.3], y = [0.1, 0.13], n = [6, 1] }
model = "neo-hookean-compressible"
shear_modulus = 2.0e6
bulk_modulus = 5.0e6
density = 300.0
body_force = [100.0, -3000.0]

[[SOLID.boundary]]
name = "left"
type = "displacement"
value = [0.0, 0.0]
"#;
    let rest = |which: &[&str]| -> String {
        let mut text = "[time]\ndt = 0.005\nend = 0.1\nscheme = \"bdf2\"\n\n[solver.newton]\nabs_tol = 1e-10\n\n".to_string();
        for (name, point) in [("heavy_tip_y", "[0.35, 0.02]"), ("light_tip_y", "[0.3, 0.13]")] {
            if which.iter().any(|w| name.starts_with(w)) {
                text += &format!("[[output.probe]]\nname = \"{name}\"\nfield = \"displacement\"\ncomponent = 1\npoint = {point}\n\n");
            }
        }
        text
    };
    let (_, both) = run("falling-two", &case_of("two bars", "", &[heavy, light], &rest(&["heavy", "light"])));
    let (_, heavy_alone) = run("falling-heavy", &case_of("heavy alone", "", &[heavy], &rest(&["heavy"])));
    let (_, light_alone) = run("falling-light", &case_of("light alone", "", &[light], &rest(&["light"])));
    let history = |out: &Path, name: &str| -> Vec<f64> {
        let text = std::fs::read_to_string(out.join("history.csv")).unwrap();
        let mut lines = text.lines();
        let column = lines.next().unwrap().split(',').position(|h| h == name).unwrap();
        lines.map(|l| l.split(',').nth(column).unwrap().parse().unwrap()).collect()
    };
    for (name, alone) in [("heavy_tip_y", &heavy_alone), ("light_tip_y", &light_alone)] {
        let (a, b) = (history(&both, name), history(alone, name));
        assert_eq!(a.len(), 21, "{name}: the start and every step");
        let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let worst = a.iter().zip(&b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale;
        println!("{name}: largest {scale:.6e}, together against alone {worst:.2e}");
        assert!(scale > 1e-4, "{name}: the bar falls");
        assert!(worst < 1e-12, "{name}: {worst}");
    }
}

/// Two leaflets in a channel, one the mirror image of the other across its centre line y = 0
/// (a full model of a symmetric valve), against the half model: one leaflet above a symmetry
/// line. The fluid meshes are mirror images too (`rectangle`, alternating diagonals, rows of a
/// multiple of 4), so the full model's solution is the half model's and its mirror image: each
/// leaflet's tip moves as the half model's (the lower's mirrored), and the full model's coupling
/// force (on both leaflets) is twice the half model's along the channel and 0 across it; to
/// 1e-10 of their size (measured: 1e-13). Navier-Stokes, 10 steps.
#[test]
fn two_mirrored_leaflets_move_as_the_half_model_of_one() {
    // The upper leaflet: hinged on the wall y = 2 ("top", t = 1), its tip ("bottom", t = 0) at
    // y = 0.9, 0.1 thick, coupled on its upstream side ("left", s = 0).
    let upper = r#"[SOLID]
name = "upper"
mesh = { kind = "quadrilateral", corners = [[2.5, 0.9], [2.6, 0.9], [2.1, 2.0], [2.0, 2.0]], n = [1, 8] }
surface = "left"
model = "neo-hookean"
shear_modulus = 200.0
density = 1.0

[[SOLID.boundary]]
name = "top"
type = "displacement"
value = [0.0, 0.0]
"#;
    // Its mirror image (the corners reordered to stay counter-clockwise: hinge "bottom", tip
    // "top", upstream side "left").
    let lower = r#"[SOLID]
name = "lower"
mesh = { kind = "quadrilateral", corners = [[2.0, -2.0], [2.1, -2.0], [2.6, -0.9], [2.5, -0.9]], n = [1, 8] }
surface = "left"
model = "neo-hookean"
shear_modulus = 200.0
density = 1.0

[[SOLID.boundary]]
name = "bottom"
type = "displacement"
value = [0.0, 0.0]
"#;
    let common = r#"
[fluid]
density = 1.0
viscosity = 0.05

[time]
dt = 0.02
end = 0.2

[solver.linear]
method = "direct"

[solver.newton]
abs_tol = 1e-11

[[boundary]]
name = "left"
type = "velocity"
value = ["1 - y*y/4", 0.0]

[[boundary]]
name = "top"
type = "no-slip"

[[output.probe]]
name = "upper_tip_x"
field = "displacement"
component = 0
point = [2.5, 0.9]

[[output.probe]]
name = "upper_tip_y"
field = "displacement"
component = 1
point = [2.5, 0.9]
"#;
    let half = format!(
        "[mesh]\nkind = \"rectangle\"\nx = [0.0, 8.0]\ny = [0.0, 2.0]\nn = [32, 8]\n{common}\n\
         [[boundary]]\nname = \"bottom\"\ntype = \"symmetry\"\nnormal_axis = 1\n"
    );
    let full = format!(
        "[mesh]\nkind = \"rectangle\"\nx = [0.0, 8.0]\ny = [-2.0, 2.0]\nn = [32, 16]\n{common}\n\
         [[boundary]]\nname = \"bottom\"\ntype = \"no-slip\"\n\n\
         [[output.probe]]\nname = \"lower_tip_x\"\nfield = \"displacement\"\ncomponent = 0\npoint = [2.5, -0.9]\n\n\
         [[output.probe]]\nname = \"lower_tip_y\"\nfield = \"displacement\"\ncomponent = 1\npoint = [2.5, -0.9]\n"
    );
    let navier_stokes = "model = \"navier-stokes\"\n";
    let (one, _) = run("half-valve", &case_of("half valve", navier_stokes, &[upper], &half));
    let (two, _) = run("full-valve", &case_of("full valve", navier_stokes, &[upper, lower], &full));
    let q = |s: &RunSummary, name: &str| s.quantities[name];
    let tip = q(&one, "upper_tip_x").hypot(q(&one, "upper_tip_y"));
    for (name, mirror) in [("tip_x", 1.0), ("tip_y", -1.0)] {
        let (h, upper, lower) = (q(&one, &format!("upper_{name}")), q(&two, &format!("upper_{name}")), q(&two, &format!("lower_{name}")));
        println!("{name}: half model {h:.12e}, full model {upper:.12e} and mirrored {:.12e}", mirror * lower);
        // Measured: 1e-13 and less.
        assert!((upper - h).abs() < 1e-10 * tip && (mirror * lower - h).abs() < 1e-10 * tip, "{name}");
    }
    assert!(tip > 0.05, "the leaflet opens: {tip}");
    let (fx, fy) = (q(&one, "coupling_force_x"), q(&one, "coupling_force_y"));
    let force = fx.hypot(fy);
    println!(
        "coupling force: half model ({fx:.12e}, {fy:.12e}), full model ({:.12e}, {:.12e})",
        q(&two, "coupling_force_x"),
        q(&two, "coupling_force_y")
    );
    assert!((q(&two, "coupling_force_x") - 2.0 * fx).abs() < 1e-10 * force);
    assert!(q(&two, "coupling_force_y").abs() < 1e-10 * force);
    assert_eq!(one.steps, 10);
    assert_eq!(two.dofs["solid"], 2 * one.dofs["solid"]);
}

/// The two-body contact patch test (`tests/contact.rs`) with the blocks as two `[[solid]]`
/// tables: an upper block of 4 x 2 cells pressed by a dead load onto a lower block of 3 x 2
/// cells (the meshes do not match along y = 0.5), `against = "lower/top"`, the other solid's
/// boundary. The contact pressure is the load, uniform, to 1e-12.
#[test]
fn two_solids_in_contact_carry_a_uniform_contact_pressure() {
    let block = |name: &str, y: &str, n: &str, loads: &str| {
        format!(
            "[SOLID]\nname = \"{name}\"\nmesh = {{ kind = \"rectangle\", x = [0.0, 1.0], y = {y}, n = {n} }}\nmodel = \"neo-hookean\"\nshear_modulus = 1.0\n\n\
             [[SOLID.boundary]]\nname = \"left\"\ntype = \"displacement\"\ncomponents = [0]\nvalue = [0.0, 0.0]\n\n{loads}"
        )
    };
    let lower = block(
        "lower",
        "[0.0, 0.5]",
        "[3, 2]",
        "[[SOLID.boundary]]\nname = \"bottom\"\ntype = \"displacement\"\ncomponents = [1]\nvalue = [0.0, 0.0]\n",
    );
    let upper = block(
        "upper",
        "[0.5, 1.0]",
        "[4, 2]",
        "[[SOLID.boundary]]\nname = \"top\"\ntype = \"traction\"\nvalue = [0.0, -0.2]\n\n[[SOLID.contact]]\nboundary = \"bottom\"\nagainst = \"lower/top\"\n",
    );
    let (s, out) = run("blocks", &case_of("two blocks", "", &[&lower, &upper], "[solver.newton]\nabs_tol = 1e-14\nrel_tol = 1e-14\n"));
    let q = |name: &str| s.quantities[name];
    println!("two blocks: {:?}", s.quantities);
    assert!((q("upper/bottom_contact_force") - 0.2).abs() < 1e-12);
    assert!((q("upper/bottom_contact_pressure_max") - 0.2).abs() < 1e-12);
    assert!(q("upper/bottom_gap_min").abs() < 1e-12);
    // Solid output with contact against another solid: every node has a finite gap.
    let entries = read_pvd(&out.join("solution.pvd")).unwrap();
    let grid = read_vtu(&entries.last().unwrap().resolve(&out.join("solution.pvd"))).unwrap();
    assert!(grid.point_array("contact_gap").unwrap().values.iter().all(|g| g.is_finite()));
}

/// Two leaflets closing on each other (the full model of a symmetric valve: the upper leaflet's
/// tip `against` the lower's, mortar contact between two solids, the fluid between them cut off
/// once they touch) beside the half model of one closing on a symmetry line (a contact plane),
/// under a reversed pressure difference of 1.5, to t = 8. Both close at t = 1.6 and seal: the
/// flux balance holds to round-off every step (the cut cells' walls hold the fluid), no tip
/// penetrates, and the jump across the valve is the applied one (measured: 1.5e-5 and 1.9e-4
/// relative; no penetration beyond 1e-12). Not the same yet (measured, an open item): the full
/// model's tips still slide at t = 8 (the upper tip moved 7.5e-3 from t = 5, the half model's
/// 2.6e-4), with a flux of 1.7e-3 of its peak, steady since t = 5 (the half model's 1e-4 and
/// falling), and its leaflets carry 5.4 % less force along the channel than twice the half
/// model's; its cut is not the mirror image of the half model's (13 cells against 2 x 7: the
/// layers are projected onto the other tip, not onto the line).
#[test]
fn two_leaflets_close_on_each_other_and_seal() {
    let leaflet = |name: &str, corners: &str, hinge: &str, contact: &str| {
        format!(
            "[SOLID]\nname = \"{name}\"\nmesh = {{ kind = \"quadrilateral\", corners = {corners}, n = [1, 11] }}\nsurface = \"left\"\n\
             model = \"neo-hookean\"\nshear_modulus = 3000.0\n\n[[SOLID.boundary]]\nname = \"{hinge}\"\ntype = \"displacement\"\nvalue = [0.0, 0.0]\n\n{contact}"
        )
    };
    let plane = "[[SOLID.contact]]\nboundary = \"bottom\"\npoint = [0.0, 0.0]\nnormal = [0.0, 1.0]\n";
    let against = "[[SOLID.contact]]\nboundary = \"bottom\"\nagainst = \"lower/top\"\n";
    let upper_corners = "[[2.6, 0.1], [2.7, 0.1], [2.05, 1.0], [1.95, 1.0]]";
    let lower = leaflet("lower", "[[1.95, -1.0], [2.05, -1.0], [2.7, -0.1], [2.6, -0.1]]", "bottom", "");
    let common = r#"
[fluid]
density = 1.0
viscosity = 0.25

[time]
dt = 0.1
end = 8.0
output_every = 1000

[solver.linear]
method = "direct"

[output]
animation = false

[[boundary]]
name = "left"
type = "pressure"
value = [0.0]

[[boundary]]
name = "right"
type = "pressure"
value = ["1.5*min(t, 1)"]

[[boundary]]
name = "top"
type = "no-slip"

[[output.boundary_integral]]
name = "inlet_flux"
boundary = "left"
kind = "flux"

[[output.boundary_integral]]
name = "outlet_flux"
boundary = "right"
kind = "flux"

[[output.probe]]
name = "p_up"
field = "pressure"
point = [1.0, 0.5]

[[output.probe]]
name = "p_down"
field = "pressure"
point = [4.5, 0.5]

[[output.probe]]
name = "tip_x"
field = "displacement"
component = 0
point = [2.6, 0.1]
"#;
    let half = format!(
        "[mesh]\nkind = \"rectangle\"\nx = [0.0, 6.0]\ny = [0.0, 1.0]\nn = [24, 8]\n{common}\n[[boundary]]\nname = \"bottom\"\ntype = \"symmetry\"\nnormal_axis = 1\n"
    );
    let full = format!("[mesh]\nkind = \"rectangle\"\nx = [0.0, 6.0]\ny = [-1.0, 1.0]\nn = [24, 16]\n{common}\n[[boundary]]\nname = \"bottom\"\ntype = \"no-slip\"\n");
    let navier_stokes = "model = \"navier-stokes\"\n";
    let (one, half_out) = run("closing-half", &case_of("half valve", navier_stokes, &[&leaflet("upper", upper_corners, "top", plane)], &half));
    let (two, full_out) =
        run("closing-full", &case_of("full valve", navier_stokes, &[&leaflet("upper", upper_corners, "top", against), &lower], &full));
    let columns = |out: &Path| -> std::collections::BTreeMap<String, Vec<f64>> {
        let text = std::fs::read_to_string(out.join("history.csv")).unwrap();
        let mut lines = text.lines();
        let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
        let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
        header.iter().enumerate().map(|(i, h)| (h.clone(), rows.iter().map(|r| r[i]).collect())).collect()
    };
    let (h, f) = (columns(&half_out), columns(&full_out));
    for (name, c, contact) in [("half", &h, "bottom"), ("full", &f, "upper/bottom")] {
        let (q_in, q_out) = (&c["inlet_flux"], &c["outlet_flux"]);
        let peak = q_in.iter().fold(0.0f64, |m, q| m.max(q.abs()));
        let balance = q_in.iter().zip(q_out).map(|(a, b)| (a + b).abs()).fold(0.0, f64::max) / peak;
        let last = q_in.len() - 1;
        let (settled, jump) = (q_in[last].abs() / peak, c["p_down"][last] - c["p_up"][last]);
        let gap = c[&format!("{contact}_gap_min")].iter().fold(f64::INFINITY, |m, g| m.min(*g));
        let closed_from = c["time"][c[&format!("{contact}_contact_force")].iter().position(|&v| v > 0.0).unwrap_or(last)];
        // How far the upper tip moves from t = 5 to t = 8 (steps 50 to 80).
        let creep = (c["tip_x"][last] - c["tip_x"][last - 30]).abs();
        println!(
            "{name}: closed from t = {closed_from}, gap min {gap:.2e}, flux balance {balance:.2e} of the peak {peak:.4}; at t = 8: \
             jump {jump:.8}, flux {settled:.2e} of the peak, {} cells cut off, coupling force x {:.6}; tip moved {creep:.3e} from t = 5",
            c["closed_gap_cells"][last], c["coupling_force_x"][last]
        );
        assert!(closed_from < 2.0 && c[&format!("{contact}_contact_force")][last] > 0.0, "{name}: closed");
        assert!(balance < 1e-12, "{name}: flux balance {balance}");
        assert!(gap >= -1e-6, "{name}: penetration {gap}");
        assert!(c["closed_gap_cells"][last] > 0.0, "{name}: the gap is cut off");
        assert!((jump - 1.5).abs() < 5e-4 * 1.5, "{name}: jump {jump}");
        let settled_limit = if name == "half" { 2e-4 } else { 3e-3 };
        assert!(settled < settled_limit, "{name}: the flux through the closed valve {settled}");
    }
    // A quantity named by a solid's boundary is plotted in the plots folder (`/` as `.`).
    assert!(full_out.join("plots/upper.bottom_contact_force.png").exists());
    let (fx_half, fx_full) = (one.quantities["coupling_force_x"], two.quantities["coupling_force_x"]);
    println!("force along the channel: full {fx_full:.6}, twice the half {:.6} ({:+.2} %)", 2.0 * fx_half, 100.0 * (fx_full / (2.0 * fx_half) - 1.0));
    assert!((fx_full - 2.0 * fx_half).abs() < 0.07 * (2.0 * fx_half).abs(), "forces {fx_full} and twice {fx_half}");
}
