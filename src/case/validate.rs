//! [`Case::validate`]: the range and consistency checks that need no mesh, one function per table
//! of the case file. The problems are collected in the order the tables are checked.

use super::{
    spelled, BoundaryIntegralKind, BoundarySpec, BoundaryType, Case, CaseError, Expr, FibreSpec, FlowModel, MeshSpec, ProbeField, RunKind, Scalar,
    SolidBoundaryType, SolidMeshSpec, SolidModel, SolidSpec, TimeFunction, MAX_CUTS, MAX_GENERATED_CELLS, MAX_STEPS,
};
use crate::discretize::fsi::MultiplierSpace;
use crate::physics::fluid::Formulation;
use std::collections::HashSet;

impl Case {
    /// Range and consistency checks that need no mesh. Returns every problem found.
    pub fn validate(&self, file: &str) -> Result<(), CaseError> {
        let mut problems = Problems(Vec::new());
        fluid(self, &mut problems);
        mesh(self, &mut problems);
        boundaries(self, &mut problems);
        body_force(self, &mut problems);
        output(self, &mut problems);
        solids(self, &mut problems);
        time(self, &mut problems);
        boundary_time_functions(self, &mut problems);
        solver(self, &mut problems);
        if problems.0.is_empty() {
            Ok(())
        } else {
            Err(CaseError::Invalid { file: file.to_string(), message: problems.0.join("\n  ") })
        }
    }
}

/// The problems found so far, in the order found.
struct Problems(Vec<String>);

impl Problems {
    /// Records a problem.
    fn push(&mut self, message: impl Into<String>) {
        self.0.push(message.into());
    }

    /// `v` must be a positive finite number.
    fn positive(&mut self, v: f64, what: &str) {
        if !(v > 0.0 && v.is_finite()) {
            self.push(format!("{what} must be a positive number, got {v}"));
        }
    }

    /// Each `(name, [lo, hi])` must be an increasing interval of finite numbers.
    fn intervals(&mut self, table: &str, axes: &[(&str, &[f64; 2])]) {
        for (name, [lo, hi]) in axes {
            if !(lo.is_finite() && hi.is_finite() && hi > lo) {
                self.push(format!("{table}.{name} = [{lo}, {hi}] must be an increasing interval [lo, hi] of finite numbers"));
            }
        }
    }

    /// Cell counts: each >= 1, and `per_cell` times their product at most [`MAX_GENERATED_CELLS`].
    fn cell_counts(&mut self, what: &str, n: &[usize], per_cell: usize) {
        if n.contains(&0) {
            self.push(format!("{what}: cell counts must be >= 1, got {n:?}"));
            return;
        }
        let cells = n.iter().try_fold(per_cell, |acc, &k| acc.checked_mul(k));
        if cells.is_none_or(|c| c > MAX_GENERATED_CELLS) {
            self.push(format!("{what} = {n:?} makes more than {MAX_GENERATED_CELLS} cells"));
        }
    }
}

/// `[fluid]`: required with a fluid `[mesh]`; without one, a solid-only run needs a material model.
fn fluid(c: &Case, p: &mut Problems) {
    match (&c.mesh, &c.fluid, c.solid.first()) {
        (Some(_), Some(f), _) => {
            p.positive(f.density, "fluid.density");
            p.positive(f.viscosity, "fluid.viscosity");
            if f.stabilization != crate::physics::fluid::Stabilization::None && c.physics.model != FlowModel::NavierStokes {
                p.push("fluid.stabilization = \"supg\" needs model = \"navier-stokes\" (Stokes flow has no convection to stabilise)");
            }
        }
        (Some(_), None, _) => p.push("a fluid mesh needs a [fluid] table (density, viscosity)"),
        (None, _, Some(s)) if s.model != SolidModel::Fixed => {}
        (None, _, _) => p.push("give a fluid [mesh], or a [solid] with a material model for a solid-only run"),
    }
}

/// `[mesh]`: the generator's parameters, and its dimension against `physics.formulation`.
fn mesh(c: &Case, p: &mut Problems) {
    let Some(mesh) = &c.mesh else { return };
    let mesh_dim = match mesh {
        MeshSpec::Rectangle { x, y, n } => {
            p.intervals("mesh", &[("x", x), ("y", y)]);
            p.cell_counts("mesh.n", n, 2);
            2
        }
        MeshSpec::Channel { length, height, n, grading } => {
            p.positive(*length, "mesh.length");
            p.positive(*height, "mesh.height");
            p.positive(*grading, "mesh.grading");
            p.cell_counts("mesh.n", n, 2);
            2
        }
        MeshSpec::Box { x, y, z, n } => {
            p.intervals("mesh", &[("x", x), ("y", y), ("z", z)]);
            p.cell_counts("mesh.n", n, 6);
            3
        }
        MeshSpec::Pipe { radius, length, n_radial, n_axial, .. } => {
            p.positive(*radius, "mesh.radius");
            p.positive(*length, "mesh.length");
            if *n_radial == 0 || *n_axial == 0 {
                p.push("mesh: n_radial and n_axial must be >= 1");
            }
            // About 6 n_radial^2 tetrahedra per layer.
            p.cell_counts("mesh: n_radial^2 x n_axial", &[*n_radial, *n_radial, *n_axial], 6);
            3
        }
        MeshSpec::Gmsh { .. } => return,
    };
    if mesh_dim != c.dim() {
        p.push(format!(
            "physics.formulation = {} needs a {}D mesh, but the mesh generator makes {mesh_dim}D meshes",
            spelled(&c.physics.formulation),
            c.dim()
        ));
    }
}

/// `[[boundary]]`: value counts per type, axis and symmetry conditions, expressions, unique names.
fn boundaries(c: &Case, p: &mut Problems) {
    let d = c.dim();
    for b in &c.boundary {
        let k = match b.kind {
            BoundaryType::Velocity | BoundaryType::Traction => d,
            BoundaryType::Pressure => 1,
            _ => 0,
        };
        if b.value.len() != k {
            p.push(format!(
                "boundary '{}' (type = {}): `value` needs {k} entr{}, got {}",
                b.name,
                spelled(&b.kind),
                if k == 1 { "y" } else { "ies" },
                b.value.len()
            ));
        }
        if b.kind == BoundaryType::Axis && c.physics.formulation != Formulation::Axisymmetric {
            p.push(format!("boundary '{}': type = \"axis\" only applies to axisymmetric runs", b.name));
        }
        symmetry(b, d, p);
        if let Some(beta) = b.backflow_stabilization {
            if !matches!(b.kind, BoundaryType::Pressure | BoundaryType::Traction | BoundaryType::Free | BoundaryType::Windkessel) {
                p.push(format!("boundary '{}': backflow_stabilization applies to traction boundaries, not type = {}", b.name, spelled(&b.kind)));
            } else if !(0.0..=1.0).contains(&beta) {
                p.push(format!("boundary '{}': backflow_stabilization must be in [0, 1], got {beta}", b.name));
            } else if c.physics.model != FlowModel::NavierStokes {
                p.push(format!("boundary '{}': backflow_stabilization needs model = \"navier-stokes\" (Stokes flow has no convection)", b.name));
            }
        }
        let normal_flow = matches!(b.kind, BoundaryType::Pressure | BoundaryType::Free | BoundaryType::Windkessel);
        match b.normal_axis {
            Some(a) if normal_flow && a >= d => p.push(format!("boundary '{}': normal_axis must be in 0..{d}, got {a}", b.name)),
            Some(_) if !normal_flow && b.kind != BoundaryType::Symmetry => p.push(format!(
                "boundary '{}': normal_axis applies to symmetry, pressure, free and windkessel boundaries, not type = {}",
                b.name,
                spelled(&b.kind)
            )),
            _ => {}
        }
        windkessel(b, p);
        for v in &b.value {
            if let Err(e) = Expr::compile(v) {
                p.push(format!("boundary '{}': {e}", b.name));
            }
            if matches!(v, Scalar::Number(x) if !x.is_finite()) {
                p.push(format!("boundary '{}': `value` entries must be finite numbers", b.name));
            }
        }
    }
    let mut names = HashSet::new();
    for b in &c.boundary {
        if !names.insert(&b.name) {
            p.push(format!("boundary '{}' is given twice", b.name));
        }
    }
}

/// A `symmetry` boundary: `normal_axis` in `0..d` or a `normal` of `d` entries, not both; and
/// `normal` on no other type.
fn symmetry(b: &BoundarySpec, d: usize, p: &mut Problems) {
    let what = format!("boundary '{}'", b.name);
    if b.kind != BoundaryType::Symmetry {
        if b.normal.is_some() {
            p.push(format!(
                "{what}: normal applies to symmetry boundaries (normal_axis to pressure, free and windkessel ones), not type = {}",
                spelled(&b.kind)
            ));
        }
        return;
    }
    match (b.normal_axis, &b.normal) {
        (Some(_), Some(_)) => p.push(format!("{what}: type = \"symmetry\" takes normal_axis or normal, not both")),
        (None, None) => p.push(format!("{what}: type = \"symmetry\" needs normal_axis in 0..{d} or normal = [...] ({d} entries)")),
        (Some(a), None) if a >= d => p.push(format!("{what}: type = \"symmetry\" needs normal_axis in 0..{d}, got {a}")),
        (_, Some(n)) => plane_normal(&what, n, d, p),
        _ => {}
    }
}

/// The `normal` of a symmetry plane: `d` finite entries, not all zero.
fn plane_normal(what: &str, n: &[f64], d: usize, p: &mut Problems) {
    if n.len() != d {
        p.push(format!("{what}: normal needs {d} entries (one per dimension), got {}", n.len()));
    }
    if n.iter().any(|x| !x.is_finite()) {
        p.push(format!("{what}: normal must be finite numbers, got {n:?}"));
    } else if n.iter().all(|&x| x == 0.0) {
        p.push(format!("{what}: normal is the zero vector: give the plane's normal"));
    }
}

/// A `windkessel` boundary: its table, `R_p >= 0`, `C >= 0`, `R_d > 0`, finite pressures, and no
/// time function.
fn windkessel(b: &BoundarySpec, p: &mut Problems) {
    let name = &b.name;
    let Some(w) = &b.windkessel else {
        if b.kind == BoundaryType::Windkessel {
            p.push(format!("boundary '{name}': type = \"windkessel\" needs windkessel = {{ proximal_resistance, compliance, distal_resistance }}"));
        }
        return;
    };
    if b.kind != BoundaryType::Windkessel {
        p.push(format!("boundary '{name}': a windkessel table goes with type = \"windkessel\", not {}", spelled(&b.kind)));
        return;
    }
    for (key, v) in [("proximal_resistance", w.proximal_resistance), ("compliance", w.compliance)] {
        if !(v >= 0.0 && v.is_finite()) {
            p.push(format!("boundary '{name}': windkessel.{key} must be a finite number >= 0, got {v}"));
        }
    }
    p.positive(w.distal_resistance, &format!("boundary '{name}': windkessel.distal_resistance"));
    for (key, v) in [("distal_pressure", Some(w.distal_pressure)), ("initial_pressure", w.initial_pressure)] {
        if let Some(v) = v.filter(|v| !v.is_finite()) {
            p.push(format!("boundary '{name}': windkessel.{key} must be a finite number, got {v}"));
        }
    }
    if b.time_function.is_some() {
        p.push(format!("boundary '{name}': a windkessel outlet takes no time_function"));
    }
}

/// `[[boundary]]` `time_function`: its duration, period or rise must be positive.
fn boundary_time_functions(c: &Case, p: &mut Problems) {
    for b in &c.boundary {
        match &b.time_function {
            Some(TimeFunction::Ramp { duration: v })
            | Some(TimeFunction::Sine { period: v, .. })
            | Some(TimeFunction::QuarterSineHold { rise: v })
            | Some(TimeFunction::Table { period: Some(v), .. }) => {
                p.positive(*v, &format!("boundary '{}': time_function duration/period/rise", b.name))
            }
            _ => {}
        }
    }
}

/// `body_force` (of the fluid) and `solid.body_force`: one expression per dimension.
fn body_force(c: &Case, p: &mut Problems) {
    let d = c.dim();
    let solids = c.solid.iter().map(|s| (solid_key(c, s, "solid.body_force"), s.body_force.as_ref()));
    let forces = std::iter::once(("body_force".to_string(), c.body_force.as_ref())).chain(solids);
    for (key, f) in forces {
        let Some(f) = f else { continue };
        if f.len() != d {
            p.push(format!("{key} needs {d} entries, got {}", f.len()));
        }
        for v in f {
            if let Err(e) = Expr::compile(v) {
                p.push(format!("{key}: {e}"));
            }
        }
    }
}

/// `[output]`: probes, domain quantities, boundary integrals and combinations (with the `[time]`
/// checks of an FSI run between them, where they have always been reported).
fn output(c: &Case, p: &mut Problems) {
    probes(c, p);
    if c.mesh.is_none() {
        for q in &c.output.domain {
            p.push(format!("domain quantity '{}': needs a fluid [mesh]", q.name));
        }
    }
    fsi_time(c, p);
    let d = c.dim();
    for (q, slab) in c.output.domain.iter().filter_map(|q| q.slab.map(|s| (q, s))) {
        if slab.axis.index() >= d {
            p.push(format!("domain quantity '{}': slab.axis \"{}\" is not an axis of a {d}D model", q.name, ["x", "y", "z"][slab.axis.index()]));
        }
        if !(slab.from.is_finite() && slab.to.is_finite() && slab.from < slab.to) {
            p.push(format!("domain quantity '{}': slab needs finite from < to, got from = {}, to = {}", q.name, slab.from, slab.to));
        }
    }
    for b in &c.output.boundary_integral {
        if b.kind == BoundaryIntegralKind::Force && b.component >= d {
            p.push(format!("boundary_integral '{}': component must be < {d}", b.name));
        }
    }
    combinations(c, p);
    open_area(c, p);
    if let Some(slice) = &c.output.slice {
        if d != 3 || c.mesh.is_none() {
            p.push("[output.slice] is for 3D runs with a fluid mesh (a 2D run's speed.png shows the whole plane)");
        }
        if slice.at.is_some_and(|a| !a.is_finite()) {
            p.push(format!("[output.slice] at = {:?} must be a finite number", slice.at));
        }
    }
}

/// `[[output.probe]]`: point, field and component.
fn probes(c: &Case, p: &mut Problems) {
    let d = c.dim();
    let moving_solid = c.solid.first().is_some_and(|s| s.model != SolidModel::Fixed);
    for probe in &c.output.probe {
        if probe.point.len() != d {
            p.push(format!("probe '{}': point needs {d} coordinates", probe.name));
        }
        if probe.point.iter().any(|x| !x.is_finite()) {
            p.push(format!("probe '{}': point coordinates must be finite numbers", probe.name));
        }
        if probe.field == ProbeField::Displacement && !moving_solid {
            p.push(format!("probe '{}': displacement probes need a solid with a material model (solid-only or FSI runs)", probe.name));
        }
        if matches!(probe.field, ProbeField::Velocity | ProbeField::Displacement) && probe.component >= d {
            p.push(format!("probe '{}': component must be < {d}", probe.name));
        }
    }
}

/// `[time]` of an FSI run: required.
fn fsi_time(c: &Case, p: &mut Problems) {
    if c.kind() != RunKind::Fsi {
        return;
    }
    if c.time.is_none() {
        p.push("an FSI run (fluid mesh and a solid material model) needs a [time] table");
    }
}

/// `[[output.combination]]`: each term names a quantity defined before it; `[[output.oscillation]]`
/// and `[output.cycles]`: quantities of a time-dependent run.
fn combinations(c: &Case, p: &mut Problems) {
    let builtin = c.run_quantities();
    // Every quantity is one column of history.csv: its name once.
    let own = c.output.probe.iter().map(|q| &q.name).chain(c.output.boundary_integral.iter().map(|q| &q.name));
    let own = own.chain(c.output.domain.iter().map(|q| &q.name)).chain(c.output.combination.iter().map(|q| &q.name));
    let mut seen: HashSet<&str> = HashSet::new();
    for name in own {
        if builtin.contains(name) {
            p.push(format!("output quantity '{name}': the run writes a quantity of that name itself; choose another"));
        } else if !seen.insert(name) {
            p.push(format!("output quantity '{name}' is defined twice"));
        }
    }
    let mut known: HashSet<&str> = c.output.probe.iter().map(|q| q.name.as_str()).collect();
    known.extend(c.output.boundary_integral.iter().map(|q| q.name.as_str()));
    known.extend(c.output.domain.iter().map(|q| q.name.as_str()));
    known.extend(builtin.iter().map(String::as_str));
    for comb in &c.output.combination {
        for (q, _) in &comb.terms {
            if !known.contains(q.as_str()) {
                p.push(format!("combination '{}': unknown quantity '{q}' (define it before)", comb.name));
            }
        }
        known.insert(&comb.name);
    }
    let mut written: HashSet<String> = HashSet::new();
    for o in &c.output.oscillation {
        for suffix in ["mean", "amplitude", "frequency"] {
            let name = format!("{}_{suffix}", o.quantity);
            if known.contains(name.as_str()) || !written.insert(name.clone()) {
                p.push(format!("oscillation of '{}': its quantity {name} is already defined", o.quantity));
            }
        }
        if !known.contains(o.quantity.as_str()) {
            p.push(format!("oscillation: unknown quantity '{}'", o.quantity));
        }
        if !(o.from >= 0.0 && o.from.is_finite()) {
            p.push(format!("oscillation of '{}': `from` must be a finite time >= 0, got {}", o.quantity, o.from));
        }
        if c.time.is_none() {
            p.push(format!("oscillation of '{}': needs a time-dependent run ([time])", o.quantity));
        }
    }
    if let Some(cycles) = &c.output.cycles {
        p.positive(cycles.period, "output.cycles.period");
        if !(cycles.start >= 0.0 && cycles.start.is_finite()) {
            p.push(format!("output.cycles.start must be a finite time >= 0, got {}", cycles.start));
        }
        for name in known.iter().filter(|n| n.starts_with("cycle_")) {
            p.push(format!("output quantity '{name}': with [output.cycles] the names cycle_* are its own; choose another"));
        }
        if c.time.is_none() {
            p.push("output.cycles: needs a time-dependent run ([time])");
        }
        let named = std::iter::once(("flux", &cycles.flux)).chain(cycles.contact_force.iter().map(|f| ("contact_force", f)));
        let listed = cycles.peak.iter().map(|q| ("peak", q)).chain(cycles.forward_peak.iter().map(|q| ("forward_peak", q)));
        let listed = listed.chain(cycles.forward_mean.iter().map(|q| ("forward_mean", q)));
        for (key, name) in named.chain(listed) {
            if !known.contains(name.as_str()) {
                p.push(format!("output.cycles.{key}: unknown quantity '{name}'"));
            }
        }
    }
}

/// `[output.open_area]`: 3D FSI runs; a finite plane and a positive factor.
fn open_area(c: &Case, p: &mut Problems) {
    let Some(spec) = &c.output.open_area else {
        return;
    };
    if c.kind() != RunKind::Fsi || c.dim() != 3 {
        p.push("output.open_area is for 3D FSI runs (a fluid mesh, a solid and formulation = \"3d\")");
    }
    if !spec.at.is_finite() {
        p.push(format!("output.open_area.at must be finite, got {}", spec.at));
    }
    p.positive(spec.scale, "output.open_area.scale");
}

/// `key` of the solid `s`: as it is with one solid, `solid 'NAME': key` with several.
fn solid_key(c: &Case, s: &SolidSpec, key: &str) -> String {
    match (&s.name, c.solid.len() > 1) {
        (Some(name), true) => format!("solid '{name}': {key}"),
        _ => key.to_string(),
    }
}

/// `[solid]`, or several `[[solid]]` tables: each named (uniquely, without `/`), the options of
/// the whole solid the same in each (see [`Case::first_solid`]), and each checked as one solid
/// (its problems prefixed by its name).
fn solids(c: &Case, p: &mut Problems) {
    let [first, ..] = c.solid.as_slice() else { return };
    if c.solid.len() == 1 {
        return solid(c, first, p);
    }
    for (k, s) in c.solid.iter().enumerate() {
        let Some(name) = s.name.as_deref() else {
            p.push(format!("[[solid]] {}: several solids need a name each (name = \"...\")", k + 1));
            continue;
        };
        if name.is_empty() || name.contains('/') || name.contains('+') {
            p.push(format!("[[solid]] {}: name = {name:?} must be non-empty, without '/' or '+'", k + 1));
        }
        if c.solid[..k].iter().any(|o| o.name.as_deref() == Some(name)) {
            p.push(format!("[[solid]] {}: the name '{name}' is given twice", k + 1));
        }
    }
    // Each option of the whole solid as a text to compare.
    type Spelled = fn(&SolidSpec) -> String;
    let shared: [(&str, Spelled); 10] = [
        ("model (fixed or a material law)", |s| (s.model == SolidModel::Fixed).to_string()),
        ("multiplier", |s| spelled(&s.multiplier)),
        ("covered_fluid", |s| spelled(&s.covered_fluid)),
        ("film_pressure", |s| spelled(&s.film_pressure)),
        ("film_squeeze", |s| s.film_squeeze.to_string()),
        ("eps_hat", |s| s.eps_hat.to_string()),
        ("min_move_quality", |s| s.min_move_quality.to_string()),
        ("boundary_cuts", |s| spelled(&s.boundary_cuts)),
        ("min_cut_quality", |s| s.min_cut_quality.to_string()),
        ("loading", |s| format!("{{ steps = {}, mode = {} }}", s.loading.steps, spelled(&s.loading.mode))),
    ];
    // The pressure field is the whole solid's: a mixed law (`neo-hookean`) in every solid or in none.
    let mixed = |s: &SolidSpec| s.model == SolidModel::NeoHookean;
    for s in &c.solid[1..] {
        for (what, of) in &shared {
            if of(s) != of(first) {
                p.push(solid_key(c, s, &format!("{what} must be that of the first solid (the whole solid's): {} against {}", of(s), of(first))));
            }
        }
        if mixed(s) != mixed(first) && s.model != SolidModel::Fixed && first.model != SolidModel::Fixed {
            p.push(solid_key(
                c,
                s,
                &format!(
                    "model = {} and the first solid's {}: the solids' laws must all be mixed (\"neo-hookean\", with a pressure field) or all displacement-based",
                    spelled(&s.model),
                    spelled(&first.model)
                ),
            ));
        }
    }
    for s in &c.solid {
        let mut own = Problems(Vec::new());
        solid(c, s, &mut own);
        for problem in own.0 {
            p.push(solid_key(c, s, &problem));
        }
    }
    // Contacts between boundaries, named in full: each pair once, over all tables, and no
    // boundary against itself.
    // (What one table's own check reports, `against` itself or a pair twice in the table, is not
    // reported again.)
    let mut pairs: Vec<(String, String, usize)> = Vec::new();
    for (k, s) in c.solid.iter().enumerate() {
        for contact in &s.contact {
            let Some(against) = &contact.against else { continue };
            let (a, b) = (c.solid_boundary(k, &contact.boundary), c.solid_boundary(k, against));
            if a == b && against != &contact.boundary {
                p.push(solid_key(c, s, &format!("solid.contact '{}': '{against}' is the boundary itself", contact.boundary)));
            } else if pairs.iter().any(|(x, y, table)| *table != k && ((x, y) == (&a, &b) || (x, y) == (&b, &a))) {
                p.push(solid_key(c, s, &format!("solid.contact '{}': '{a}' and '{b}' are in contact already: give the pair once", contact.boundary)));
            }
            pairs.push((a, b, k));
        }
    }
}

/// `[solid]`: coupling surface, material, multiplier, `eps_hat`, `min_move_quality`, mesh, placement and load steps.
fn solid(c: &Case, solid: &SolidSpec, p: &mut Problems) {
    if c.mesh.is_some() && solid.surface.is_none() {
        p.push("solid.surface (the solid boundary coupled to the fluid) is required with a fluid");
    }
    if let Some(names) = &solid.surface {
        let list = names.names();
        if list.is_empty() || list.iter().any(|n| n.is_empty()) {
            p.push("solid.surface: give one boundary name or a non-empty list of names");
        }
        if (1..list.len()).any(|i| list[..i].contains(&list[i])) {
            p.push(format!("solid.surface = {:?}: a boundary is named twice", names.names()));
        }
    }
    if solid.model != SolidModel::Fixed {
        solid_material(c, solid, p);
    } else if solid.fibres.is_some() {
        p.push("solid.fibres reinforce a material law: give solid.model (e.g. \"neo-hookean\")");
    } else if !solid.contact.is_empty() {
        p.push("solid.contact needs a deforming solid: give solid.model (e.g. \"neo-hookean\")");
    }
    if solid.film_squeeze && solid.film_pressure != crate::discretize::fsi::FilmPressure::Reynolds {
        p.push("solid.film_squeeze is the squeeze term of Reynolds' equation: it needs film_pressure = \"reynolds\"");
    }
    if solid.multiplier == MultiplierSpace::P1DiscontinuousTraceMode && c.dim() == 3 {
        p.push("solid.multiplier = \"p1-discontinuous-trace-mode\" is 2D only (plane or axisymmetric)");
    }
    if !(solid.eps_hat > 0.0 && solid.eps_hat <= 0.5) {
        p.push(format!("solid.eps_hat must lie in (0, 0.5], got {}", solid.eps_hat));
    }
    if !(solid.min_move_quality > 0.0 && solid.min_move_quality < 1.0) {
        p.push(format!("solid.min_move_quality must lie in (0, 1), got {}", solid.min_move_quality));
    }
    if !(0.0..1.0).contains(&solid.min_cut_quality) {
        p.push(format!("solid.min_cut_quality must lie in [0, 1), got {}", solid.min_cut_quality));
    }
    solid_mesh(c, solid, p);
    solid_placement(c, solid, p);
    if solid.loading.steps > MAX_STEPS {
        p.push(format!("solid.loading.steps = {} is more than {MAX_STEPS}", solid.loading.steps));
    }
}

/// `[[solid.contact]]`: a boundary name, a point and a non-zero normal of the dimension, each
/// boundary once; `fluid_cut_off` a length >= 0; or (2D) another boundary it is `against`.
fn contact(c: &Case, solid: &SolidSpec, p: &mut Problems) {
    let d = c.dim();
    for (i, k) in solid.contact.iter().enumerate() {
        let what = format!("solid.contact '{}'", k.boundary);
        if k.boundary.is_empty() {
            p.push("solid.contact: give the boundary that may touch the plane");
        }
        if solid.contact[..i].iter().any(|o| o.boundary == k.boundary) {
            p.push(format!("{what} is given twice"));
        }
        if let Some(against) = &k.against {
            if !k.point.is_empty() || !k.normal.is_empty() {
                p.push(format!("{what}: give either a plane (point and normal) or a boundary it is 'against', not both"));
            }
            if d != 2 {
                p.push(format!("{what}: contact against another boundary ('{against}') is implemented in 2D (plane and axisymmetric) only"));
            }
            if against == &k.boundary {
                p.push(format!("{what}: a boundary cannot be 'against' itself"));
            }
            if solid.contact[..i].iter().any(|o| o.against.as_deref() == Some(&k.boundary) && o.boundary == *against) {
                p.push(format!("{what}: '{against}' is already against '{}': give the pair once", k.boundary));
            }
            fluid_cut_off(k, &what, p);
            continue;
        }
        for (key, v) in [("point", &k.point), ("normal", &k.normal)] {
            if v.len() != d {
                p.push(format!("{what}: {key} needs {d} entries, got {}", v.len()));
            }
            if v.iter().any(|x| !x.is_finite()) {
                p.push(format!("{what}: {key} must be finite numbers"));
            }
        }
        if k.normal.iter().all(|&x| x == 0.0) {
            p.push(format!("{what}: the normal is the zero vector"));
        }
        fluid_cut_off(k, &what, p);
    }
}

/// `fluid_cut_off`, if given: a finite length >= 0.
fn fluid_cut_off(k: &super::ContactSpec, what: &str, p: &mut Problems) {
    if let Some(cut_off) = k.fluid_cut_off {
        if !(cut_off.is_finite() && cut_off >= 0.0) {
            p.push(format!("{what}: fluid_cut_off must be a finite length >= 0, got {cut_off}"));
        }
    }
}

/// `[solid.fibres]`: `k1 > 0`, `k2 >= 0`, `onset >= 0`, one direction entry per dimension, not a constant zero.
fn fibres(c: &Case, f: &FibreSpec, p: &mut Problems) {
    p.positive(f.k1, "solid.fibres.k1");
    if !(f.k2 >= 0.0 && f.k2.is_finite()) {
        p.push(format!("solid.fibres.k2 must be a finite number >= 0, got {}", f.k2));
    }
    if let Some(onset) = f.onset.filter(|o| !(*o >= 0.0 && o.is_finite())) {
        p.push(format!("solid.fibres.onset must be a finite number >= 0, got {onset}"));
    }
    let d = c.dim();
    if f.direction.len() != d {
        p.push(format!("solid.fibres.direction needs {d} entries, got {}", f.direction.len()));
    }
    for v in &f.direction {
        if let Err(e) = Expr::compile(v) {
            p.push(format!("solid.fibres.direction: {e}"));
        }
    }
    if f.direction.iter().all(|v| matches!(v, Scalar::Number(a) if *a == 0.0)) {
        p.push("solid.fibres.direction is the zero vector: give the fibres a direction");
    }
}

/// `[solid]` with a material model: moduli, `[solid.loading]` steps and `[[solid.boundary]]`.
fn solid_material(c: &Case, solid: &SolidSpec, p: &mut Problems) {
    let d = c.dim();
    let before = p.0.len();
    for (name, v) in [("shear_modulus", solid.shear_modulus), ("bulk_modulus", solid.bulk_modulus), ("youngs_modulus", solid.youngs_modulus)] {
        if let Some(v) = v {
            p.positive(v, &format!("solid.{name}"));
        }
    }
    if let Some(nu) = solid.poissons_ratio.filter(|nu| !(*nu > -1.0 && *nu < 0.5)) {
        p.push(format!("solid.poissons_ratio must lie in (-1, 0.5), got {nu}"));
    }
    if let Some(l) = solid.lame_lambda.filter(|l| !l.is_finite()) {
        p.push(format!("solid.lame_lambda must be a finite number, got {l}"));
    }
    if p.0.len() == before {
        match solid.moduli() {
            Ok(m) if m.bulk.is_none() && solid.model != SolidModel::NeoHookean => {
                p.push(format!("solid.model = {} needs bulk_modulus (or another elastic constant besides shear_modulus)", spelled(&solid.model)))
            }
            Ok(_) => {}
            Err(e) => p.push(e),
        }
    }
    if let Some(f) = &solid.fibres {
        fibres(c, f, p);
    }
    contact(c, solid, p);
    if !(solid.density >= 0.0 && solid.density.is_finite()) {
        p.push(format!("solid.density must be a finite number >= 0, got {}", solid.density));
    }
    if c.mesh.is_none() {
        // Solid-only: [time] means dynamics (inertia, total Lagrangian); without it the load is
        // ramped quasi-statically.
        let loading_given = solid.loading.steps != 1 || solid.loading.mode != crate::discretize::solid::Lagrangian::Updated;
        match &c.time {
            Some(_) if !(solid.density > 0.0) => {
                p.push("a solid-only run with [time] is dynamic: it needs solid.density > 0 (for a static solve, drop [time] and use solid.loading)")
            }
            Some(_) if loading_given => p.push("solid.loading applies to quasi-static runs (no [time]); a dynamic run applies its loads in time"),
            None if solid.density > 0.0 => p.push("solid.density (inertia) needs a time-dependent run: add [time]"),
            _ => {}
        }
    }
    if solid.loading.steps == 0 {
        p.push("solid.loading.steps must be >= 1");
    }
    for b in &solid.boundary {
        let k = match b.kind {
            SolidBoundaryType::Pressure => 1,
            SolidBoundaryType::Symmetry => 0,
            SolidBoundaryType::Displacement | SolidBoundaryType::Traction => d,
        };
        if b.value.len() != k {
            p.push(format!("solid boundary '{}': `value` needs {k} entries, got {}", b.name, b.value.len()));
        }
        if b.components.as_ref().is_some_and(|c| c.iter().any(|&a| a >= d)) {
            p.push(format!("solid boundary '{}': components must be < {d}", b.name));
        }
        let what = format!("solid boundary '{}'", b.name);
        match (&b.normal, b.kind) {
            (None, SolidBoundaryType::Symmetry) => p.push(format!("{what}: type = \"symmetry\" needs normal = [...] ({d} entries)")),
            (Some(n), SolidBoundaryType::Symmetry) => plane_normal(&what, n, d, p),
            (Some(_), kind) => p.push(format!("{what}: normal applies to symmetry boundaries, not type = {}", spelled(&kind))),
            (None, _) => {}
        }
        if b.kind == SolidBoundaryType::Symmetry && b.components.is_some() {
            p.push(format!("{what}: type = \"symmetry\" takes no components (its normal says what is held)"));
        }
    }
}

/// `[solid.mesh]`: the generator's parameters, and its dimension against the fluid's.
fn solid_mesh(c: &Case, solid: &SolidSpec, p: &mut Problems) {
    let sd = match &solid.mesh {
        SolidMeshSpec::Rectangle { x, y, n } => {
            p.intervals("solid.mesh", &[("x", x), ("y", y)]);
            p.cell_counts("solid.mesh.n", n, 1);
            2
        }
        SolidMeshSpec::Quadrilateral { corners, n } => {
            if corners.iter().flatten().any(|c| !c.is_finite()) {
                p.push("solid.mesh.corners must be finite numbers");
            }
            p.cell_counts("solid.mesh.n", n, 1);
            2
        }
        SolidMeshSpec::Box { x, y, z, n } => {
            p.intervals("solid.mesh", &[("x", x), ("y", y), ("z", z)]);
            p.cell_counts("solid.mesh.n", n, 1);
            3
        }
        SolidMeshSpec::QuarterDisc { radius, z, n_core, n_ring, n_layers } => {
            p.positive(*radius, "solid.mesh.radius");
            p.intervals("solid.mesh", &[("z", z)]);
            let around = n_core.saturating_add(n_ring.saturating_mul(2));
            p.cell_counts("solid.mesh [n_core, n_core + 2 n_ring, n_layers]", &[*n_core, around, *n_layers], 1);
            if *n_ring == 0 {
                p.push("solid.mesh.n_ring must be >= 1");
            }
            3
        }
        SolidMeshSpec::Gmsh { .. } => return,
    };
    let d = c.dim();
    if sd != d {
        p.push(format!("solid.mesh makes a {sd}D mesh but the fluid is {d}D"));
    }
}

/// `[solid]` placement: `rotate_deg`, `pivot` and `translate`.
fn solid_placement(c: &Case, solid: &SolidSpec, p: &mut Problems) {
    let d = c.dim();
    if d == 3 && solid.rotate_deg != 0.0 {
        p.push("solid.rotate_deg applies to 2D runs only");
    }
    for (what, v) in [("pivot", &solid.pivot), ("translate", &solid.translate)] {
        if v.as_ref().is_some_and(|v| v.len() != d) {
            p.push(format!("solid.{what} needs {d} coordinates"));
        }
        if v.as_ref().is_some_and(|v| v.iter().any(|x| !x.is_finite())) {
            p.push(format!("solid.{what} must be finite numbers"));
        }
    }
    if !solid.rotate_deg.is_finite() {
        p.push(format!("solid.rotate_deg must be a finite number, got {}", solid.rotate_deg));
    }
}

/// `[time]`: step, end, output interval and the number of steps.
fn time(c: &Case, p: &mut Problems) {
    let Some(t) = &c.time else { return };
    p.positive(t.dt, "time.dt");
    p.positive(t.end, "time.end");
    if t.output_every == 0 {
        p.push("time.output_every must be >= 1");
    }
    if t.max_cuts > MAX_CUTS {
        p.push(format!("time.max_cuts = {} is more than {MAX_CUTS} (sub-steps of dt / 2^{MAX_CUTS})", t.max_cuts));
    }
    let steps = t.end / t.dt;
    if t.dt > 0.0 && t.end > 0.0 && t.end.is_finite() && steps > MAX_STEPS as f64 {
        p.push(format!("time.end / time.dt = {steps:.3e} steps, more than the {MAX_STEPS} allowed (dt = {:e}, end = {})", t.dt, t.end));
    }
}

/// `[solver]`: Newton iterations and tolerances, the linear solver's options.
fn solver(c: &Case, p: &mut Problems) {
    let n = &c.solver.newton;
    if n.max_iterations == 0 || !(n.abs_tol > 0.0) || !(n.rel_tol > 0.0) {
        p.push("solver.newton: max_iterations >= 1 and positive tolerances required");
    }
    let l = &c.solver.linear;
    if l.threads > 1024 {
        p.push(format!("solver.linear: threads = {} (1 = sequential, 0 = all cores, at most 1024)", l.threads));
    }
    if !(l.gamma > 0.0 && l.gamma.is_finite()) {
        p.push(format!("solver.linear: gamma = {} must be positive and finite (default 1e5)", l.gamma));
    }
    if !(l.krylov_tolerance > 0.0 && l.krylov_tolerance < 1.0) {
        p.push(format!("solver.linear: krylov_tolerance = {} must lie in (0, 1) (default 1e-8)", l.krylov_tolerance));
    }
    if l.krylov_max_iterations == 0 {
        p.push("solver.linear: krylov_max_iterations must be at least 1 (default 60)");
    }
    if l.method == super::LinearMethod::Petsc && !cfg!(feature = "petsc") {
        p.push(format!("solver.linear: method = \"petsc\": {}", super::WITHOUT_PETSC));
    }
}
