//! The monolithic FSI discretisation on a tiny problem: the coupling operator reproduces
//! constants, and the assembled Jacobian equals a finite difference of the assembled residual
//! (fluid, updated-Lagrangian solid and coupling blocks together).
//!
//! `CARGO_TARGET_DIR=/tmp/target-fsi cargo test --release --test fsi_coupling -- --nocapture`

use fdfsi::discretize::flow::FlowProblem;
use fdfsi::discretize::fsi::{FsiDiscretization, FsiModel, FsiProblem, StepInput};
use fdfsi::discretize::solid::SolidProblem;
use fdfsi::fem::adapt::AdaptOptions;
use fdfsi::fem::generate::{rectangle_quads, rectangle_triangles, DiagonalPattern};
use fdfsi::fem::mesh::{GeometryOrder, Mesh};
use fdfsi::fem::sparse::CscMatrix;
use fdfsi::physics::fluid::{FluidParams, Formulation, ViscousForm};
use fdfsi::physics::solid::{NeoHookeanMixed, SolidMaterial};
use std::sync::Arc;

fn rotated(mut m: Mesh<2>, deg: f64, pivot: [f64; 2]) -> Mesh<2> {
    let (s, c) = deg.to_radians().sin_cos();
    for p in m.points.iter_mut() {
        let (dx, dy) = (p[0] - pivot[0], p[1] - pivot[1]);
        *p = [pivot[0] + c * dx - s * dy, pivot[1] + s * dx + c * dy];
    }
    m
}

fn tiny_model() -> FsiModel<2> {
    let fluid = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 4, 4, DiagonalPattern::Alternating);
    let solid = rotated(rectangle_quads(0.3, 0.7, 0.47, 0.53, 2, 1, GeometryOrder::Quadratic), 20.0, [0.5, 0.5]);
    let params = FluidParams {
        viscosity: 0.1,
        density: 1.0,
        inv_dt: 0.0,
        convection: true,
        convective_form: Default::default(),
        viscous_form: ViscousForm::Stress,
        stabilization: Default::default(),
    };
    let flow = FlowProblem {
        formulation: Formulation::Plane,
        params,
        body_force: None,
        dirichlet: vec![],
        traction: vec![],
        windkessel: vec![],
        backflow: Vec::new(),
        symmetry: Vec::new(),
        pin_pressure: false,
    };
    let mat: Arc<dyn SolidMaterial> = Arc::new(NeoHookeanMixed::incompressible(5.0));
    let solid_problem = SolidProblem::new(Formulation::Plane, mat).with_displacement("bottom", &[0, 1], |_: &[f64; 2], _| [0.0; 2]);
    let problem = FsiProblem { fluid: flow, solid: solid_problem, surface: "top".into(), adapt: AdaptOptions::new(0.2) };
    FsiModel::new(problem, &fluid, solid).unwrap()
}

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }
}

#[test]
fn coupling_operator_reproduces_constants() {
    let model = tiny_model();
    let base = vec![0.0; model.solid.num_dofs()];
    let disc = FsiDiscretization::build(&model, &base, &Default::default()).unwrap();
    let mut fluid = model.problem.fluid.clone();
    let dt = 0.25;
    fluid.params.inv_dt = 1.0 / dt;
    let f = model.solid.deformation_gradients(&base).unwrap();
    let u_old = vec![0.0; disc.fluid_dofs()];
    let input =
        StepInput { fluid: &fluid, time: dt, a: 1.0 / dt, u_old: &u_old, solid_base: &base, solid_f: &f, solid_shift: None, solid_target: None };
    let (os, ol) = (disc.solid_offset(), disc.multiplier_offset());
    let c = [0.8, -1.3];
    let vel = disc.flow.velocity_field().clone();
    let sf = model.solid.displacement_field().clone();
    let mut x = vec![0.0; disc.num_dofs()];
    for node in 0..vel.nodes.num_nodes {
        for a in 0..2 {
            x[vel.dof(node, a)] = c[a];
        }
    }
    // Fluid moving, solid at rest: sum_k R_lambda(e, k, a) = c_a |gamma_f| (the P1 functions sum to 1).
    let r = disc.residual(&model, &input, &x).unwrap();
    let gamma_f = disc.adapted.gamma_f_measure();
    for a in 0..2 {
        let s: f64 = (0..disc.coupling.num_elements()).flat_map(|e| (0..2).map(move |k| (e, k))).map(|(e, k)| r[disc.multiplier_dof(e, k, a)]).sum();
        println!("component {a}: sum of constraint rows {s:.15} vs c |gamma_f| = {:.15}", c[a] * gamma_f);
        assert!((s - c[a] * gamma_f).abs() < 1e-12);
    }
    // u_f = u_s = c: every constraint row vanishes.
    for node in 0..sf.nodes.num_nodes {
        for a in 0..2 {
            x[os + sf.dof(node, a)] = c[a] * dt;
        }
    }
    let r = disc.residual(&model, &input, &x).unwrap();
    let worst = r[ol..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    println!("{} coupling elements, {} points: max |R_lambda| = {worst:.2e}", disc.coupling.num_elements(), disc.coupling.num_points());
    assert!(worst < 1e-14, "{worst:e}");
}

#[test]
fn monolithic_jacobian_matches_finite_differences_of_residual() {
    let model = tiny_model();
    let mut rng = Rng(17);
    // A deformed solid at t_n (base displacement and its F), then random unknowns.
    let nus = model.solid.displacement_field().num_dofs();
    let mut base = vec![0.0; model.solid.num_dofs()];
    for v in base[..nus].iter_mut() {
        *v = 2e-3 * rng.next();
    }
    let f = model.solid.deformation_gradients(&base).unwrap();
    let disc = FsiDiscretization::build(&model, &base, &Default::default()).unwrap();
    let mut fluid = model.problem.fluid.clone();
    let dt = 0.1;
    fluid.params.inv_dt = 1.0 / dt;
    let u_old: Vec<f64> = (0..disc.fluid_dofs()).map(|_| rng.next()).collect();
    let input =
        StepInput { fluid: &fluid, time: dt, a: 1.0 / dt, u_old: &u_old, solid_base: &base, solid_f: &f, solid_shift: None, solid_target: None };
    let (os, ol, n) = (disc.solid_offset(), disc.multiplier_offset(), disc.num_dofs());
    let mut x: Vec<f64> = (0..n).map(|_| rng.next()).collect();
    for v in x[os..os + nus].iter_mut() {
        *v *= 2e-3;
    }
    println!(
        "dofs: fluid {}, solid {}, multiplier {} ({} coupling elements); nnz {}",
        disc.fluid_dofs(),
        disc.solid_dofs(),
        disc.multiplier_dofs(),
        disc.coupling.num_elements(),
        disc.whole_pattern().nnz()
    );
    let mut k = CscMatrix::zeros(disc.whole_pattern());
    let mut rhs = vec![0.0; n];
    disc.assemble(&model, &input, &x, &vec![false; n], &mut k, &mut rhs).unwrap();
    let scale = k.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut worst = (0.0f64, 0, 0);
    let mut coupling_checked = 0;
    for j in 0..n {
        let h = 1e-6 * (1.0 + x[j].abs()) * if (os..ol).contains(&j) && j < os + nus { 1e-2 } else { 1.0 };
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[j] += h;
        xm[j] -= h;
        let rp = disc.residual(&model, &input, &xp).unwrap();
        let rm = disc.residual(&model, &input, &xm).unwrap();
        for i in 0..n {
            let fd = (rp[i] - rm[i]) / (2.0 * h);
            let kij = k.get(i, j);
            if fd != 0.0 && disc.whole_pattern().find(i, j).is_none() {
                panic!("R[{i}] depends on x[{j}] (d = {fd:e}) but ({i}, {j}) is not in the pattern");
            }
            if (i >= ol) != (j >= ol) && kij != 0.0 {
                coupling_checked += 1;
            }
            let err = (fd - kij).abs() / (1.0 + kij.abs());
            if err > worst.0 {
                worst = (err, i, j);
            }
        }
    }
    println!(
        "max |K - FD| / (1 + |K|) = {:.2e} at ({}, {}); max |K| = {scale:.2e}; {coupling_checked} nonzero coupling entries checked",
        worst.0, worst.1, worst.2
    );
    assert!(coupling_checked > 0);
    assert!(worst.0 < 1e-5, "Jacobian mismatch {:.3e} at ({}, {})", worst.0, worst.1, worst.2);
}

/// An axisymmetric membrane from the axis to the wall (model problem 3's set-up, coarse): the
/// solid end held on the axis by `u_r = 0` stays exactly on it while the membrane bulges, so
/// gamma_f reaches the axis and seals the pipe (a round-off of 3e-17 once left gamma_f a cell
/// short of the axis, a leak past the membrane's centre).
#[test]
fn a_membrane_held_on_the_axis_keeps_gamma_f_down_to_the_axis() {
    use fdfsi::case::Case;
    use fdfsi::discretize::fsi::{step, FsiState};
    use fdfsi::fem::gmsh::AnyMesh;
    let case = Case::from_toml_str(
        r#"title = "membrane on the axis"
[mesh]
kind = "rectangle"
x = [0.0, 4.0]
y = [0.0, 1.0]
n = [40, 10]
[physics]
formulation = "axisymmetric"
model = "navier-stokes"
[fluid]
density = 1.0
viscosity = 1.0
[solid]
mesh = { kind = "rectangle", x = [1.975, 2.025], y = [0.0, 1.0], n = [1, 10] }
surface = "left"
model = "neo-hookean"
shear_modulus = 2000.0
[[solid.boundary]]
name = "top"
type = "displacement"
value = [0.0, 0.0]
[[solid.boundary]]
name = "bottom"
type = "displacement"
components = [1]
value = [0.0, 0.0]
[time]
dt = 0.1
end = 1.0
[[boundary]]
name = "left"
type = "traction"
value = [1.0, 0.0]
time_function = { kind = "quarter-sine-hold", rise = 0.5 }
[[boundary]]
name = "bottom"
type = "axis"
[[boundary]]
name = "top"
type = "no-slip"
"#,
        "membrane",
    )
    .unwrap();
    let dir = std::path::Path::new(".");
    let AnyMesh::D2(mesh) = fdfsi::setup::build_mesh(&case, dir).unwrap() else { panic!("2D") };
    let model = fdfsi::setup::fsi_model::<2>(&case, &mesh, dir).unwrap();
    let mut state = FsiState::at_rest(&model);
    let newton = fdfsi::solve::newton::NewtonOptions::default();
    let mut lu = fdfsi::solve::linear::FaerLu::default();
    for _ in 0..6 {
        let (next, st) = step(&model, &state, 0.1, &mut lu, &newton).unwrap();
        let solid = model.current_solid_mesh(&next.solid_x);
        let on_axis = solid.points.iter().filter(|p| p[1].abs() < 1e-9).collect::<Vec<_>>();
        assert!(!on_axis.is_empty() && on_axis.iter().all(|p| p[1] == 0.0), "solid axis nodes {on_axis:?}");
        let min_r = st.disc.adapted.gamma_f.iter().flat_map(|g| g.vertices).map(|v| st.disc.flow.mesh.points[v][1]).fold(f64::MAX, f64::min);
        assert_eq!(min_r, 0.0, "gamma_f stops at r = {min_r} at t = {}", next.time);
        state = next;
    }
    // The membrane has moved downstream at its centre.
    let centre = model.current_solid_mesh(&state.solid_x).points.iter().filter(|p| p[1] == 0.0).map(|p| p[0]).fold(f64::MAX, f64::min);
    assert!(centre > 1.976, "centre at x = {centre}");
}

/// Error messages name the unknown of a zero pivot by field and position.
#[test]
fn unknowns_are_described_by_field_and_position() {
    let model = tiny_model();
    let base = vec![0.0; model.solid.num_dofs()];
    let disc = FsiDiscretization::build(&model, &base, &Default::default()).unwrap();
    let (vel, pres) = (&disc.flow.velocity_field(), &disc.flow.pressure_field());
    let x = disc.flow.velocity_nodes[3];
    assert_eq!(disc.describe_unknown(&model, vel.dof(3, 1)), format!("the fluid velocity y at ({:.6}, {:.6})", x[0], x[1]));
    let c = disc.flow.mesh.vertex_centroid(2);
    assert_eq!(
        disc.describe_unknown(&model, pres.dof(2 * 3 + 1, 0)),
        format!("fluid pressure dof 1 of cell 2 (centroid ({:.6}, {:.6}))", c[0], c[1])
    );
    let sf = model.solid.displacement_field();
    let x0 = model.solid.nodes_x0[5];
    assert_eq!(
        disc.describe_unknown(&model, disc.solid_offset() + sf.dof(5, 0)),
        format!("the solid displacement x at reference position ({:.6}, {:.6})", x0[0], x0[1])
    );
    let sp = &model.solid.pressure_field();
    assert_eq!(disc.describe_unknown(&model, disc.solid_offset() + sp.dof(sp.nodes.per_cell + 2, 0)), "solid pressure dof 2 of cell 1");
    assert!(disc.describe_unknown(&model, disc.num_dofs()).starts_with("out of range"));
    let e = disc.coupling.num_elements() - 1;
    let v = disc.adapted.mesh.points[disc.adapted.gamma_f[e].vertices[1]];
    assert_eq!(
        disc.describe_unknown(&model, disc.multiplier_dof(e, 1, 0)),
        format!("the multiplier x at vertex 1 of gamma_f facet {e}, ({:.6}, {:.6})", v[0], v[1])
    );
}

/// The multiplier modes removed in 3D ([`fdfsi::discretize::fsi::multiplier_kernel`]) are the kernel they
/// are meant to remove, checked directly on model problem 4's set-up (the CI mesh): each removed
/// mode z (recovered from the stored `M z` facet by facet) pairs with no free fluid velocity
/// (`<z, v> = 0`: B z vanishes in every free velocity row), integrates to zero on every facet, and
/// together they span the whole null space of that pairing, found independently by a dense
/// eigen-decomposition of the global Gram matrix B^T B (the code finds them star by star).
#[test]
fn removed_3d_multiplier_modes_span_the_null_space_of_the_pairing() {
    use faer::prelude::Solve;
    use fdfsi::case::{Case, MeshSpec, SolidMeshSpec};
    use fdfsi::discretize::fsi::FsiDiscretization;
    use fdfsi::fem::gmsh::AnyMesh;
    const D: usize = 3;
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let mut case = Case::read(&dir.join("model-problem-4.toml")).unwrap();
    case.mesh = Some(MeshSpec::Pipe { radius: 1.0, length: 4.0, n_radial: 4, n_axial: 6, quarter: true });
    case.solid.first_mut().unwrap().mesh = SolidMeshSpec::QuarterDisc { radius: 1.0, z: [1.975, 2.025], n_core: 3, n_ring: 2, n_layers: 1 };
    let AnyMesh::D3(mesh) = fdfsi::setup::build_mesh(&case, &dir).unwrap() else { panic!("3D") };
    let model = fdfsi::setup::fsi_model::<D>(&case, &mesh, &dir).unwrap();
    let disc = FsiDiscretization::build(&model, &vec![0.0; model.solid.num_dofs()], &Default::default()).unwrap();
    let c = &disc.coupling;
    let (ne, nf) = (c.num_elements(), c.nf);
    let vel = &disc.flow.velocity_field();
    let fixed: std::collections::HashSet<usize> = disc.flow.dirichlet_dofs(&model.problem.fluid, 0.0).unwrap().into_iter().map(|(d, _)| d).collect();
    let points = |e: usize| c.point_start[e]..c.point_start[e + 1];
    let area: Vec<f64> = (0..ne).map(|e| points(e).map(|q| c.weight[q]).sum()).collect();
    // B z over the free velocity dofs for a multiplier vector z[(e * D + k) * D + a]; also the
    // sum of the magnitudes of its terms, the scale it vanishes against.
    let pairing = |z: &[f64]| {
        let mut bz: std::collections::HashMap<usize, [f64; 2]> = Default::default();
        for e in 0..ne {
            let cell = vel.nodes.cell(c.fluid_cell[e]);
            for q in points(e) {
                for (i, &node) in cell.iter().enumerate() {
                    for a in 0..D {
                        let dof = vel.dof(node, a);
                        if fixed.contains(&dof) {
                            continue;
                        }
                        let t: f64 = (0..D).map(|k| c.weight[q] * c.phi_f[q * nf + i] * c.mu[q * D + k] * z[(e * D + k) * D + a]).sum();
                        let s = bz.entry(dof).or_default();
                        s[0] += t;
                        s[1] += t.abs();
                    }
                }
            }
        }
        bz
    };
    // Each removed mode: z from M z on every facet of its support (M_e, the D x D P1 mass matrix).
    assert!(!disc.kernel.is_empty(), "3D gamma_f has interior vertices: modes to remove");
    for (j, y) in disc.kernel.iter().enumerate() {
        let mut z = vec![0.0; ne * D * D];
        let mut by_facet: std::collections::BTreeMap<(usize, usize), [f64; D]> = Default::default();
        for &(i, v) in y {
            let (e, k, a) = (i / (D * D), (i / D) % D, i % D);
            by_facet.entry((e, a)).or_default()[k] = v;
        }
        for (&(e, a), rhs) in &by_facet {
            let m = faer::Mat::<f64>::from_fn(D, D, |k, l| points(e).map(|q| c.weight[q] * c.mu[q * D + k] * c.mu[q * D + l]).sum());
            let b = faer::Mat::<f64>::from_fn(D, 1, |k, _| rhs[k]);
            let sol = m.partial_piv_lu().solve(&b);
            for k in 0..D {
                z[(e * D + k) * D + a] = sol[(k, 0)];
            }
        }
        let zmax = z.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(zmax > 0.0 && by_facet.len() >= 3, "mode {j}: support of {} facets", by_facet.len());
        for (dof, [bz, scale]) in pairing(&z) {
            assert!(
                bz.abs() <= 1e-10 * scale.max(1e-300) || bz.abs() < 1e-14 * zmax,
                "mode {j}: free velocity dof {dof} sees it: {bz:e} of {scale:e}"
            );
        }
        for &(e, a) in by_facet.keys() {
            let integral: f64 = points(e).map(|q| c.weight[q] * (0..D).map(|k| c.mu[q * D + k] * z[(e * D + k) * D + a]).sum::<f64>()).sum();
            assert!(integral.abs() < 1e-10 * zmax * area[e], "mode {j}: integral {integral:e} on facet {e}");
        }
    }
    // The null space of the whole pairing, columns scaled by 1 / |F| (as the code does).
    let n = ne * D * D;
    let mut gram = faer::Mat::<f64>::zeros(n, n);
    let mut rows: std::collections::HashMap<usize, Vec<(usize, f64)>> = Default::default();
    for (e, size) in area.iter().enumerate() {
        let cell = vel.nodes.cell(c.fluid_cell[e]);
        for q in points(e) {
            for (i, &node) in cell.iter().enumerate() {
                for a in 0..D {
                    let dof = vel.dof(node, a);
                    if !fixed.contains(&dof) {
                        let row = rows.entry(dof).or_default();
                        row.extend((0..D).map(|k| ((e * D + k) * D + a, c.weight[q] * c.phi_f[q * nf + i] * c.mu[q * D + k] / size)));
                    }
                }
            }
        }
    }
    for row in rows.values_mut() {
        fdfsi::fem::sparse::sum_duplicates(row);
        for &(i, u) in row.iter() {
            for &(j, v) in row.iter() {
                gram[(i, j)] += u * v;
            }
        }
    }
    let s = gram.self_adjoint_eigen(faer::Side::Lower).unwrap().S().column_vector().to_owned();
    let max = (0..n).map(|i| s[i]).fold(0.0f64, f64::max);
    let null = (0..n).filter(|&i| s[i] < 1e-10 * max).count();
    let next = (0..n).map(|i| s[i]).filter(|&v| v >= 1e-10 * max).fold(f64::MAX, f64::min);
    println!(
        "{ne} gamma_f facets, {n} multipliers: null space of the pairing {null}, removed modes {}; smallest kept eigenvalue {:.2e} of {max:.2e}",
        disc.kernel.len(),
        next
    );
    assert_eq!(null, disc.kernel.len(), "the removed modes span the null space of the pairing");
    assert!(next > 1e-6 * max, "a clear gap between the null space and the rest");
}

/// A coupling element's solid cells of the last step stay in the pattern of a mesh with the same
/// topology (the entries hold zeros) and are dropped for another topology; the state carries
/// them through a checkpoint, so a resumed run builds the patterns of an uninterrupted one.
#[test]
fn coupling_cells_are_carried_to_a_mesh_of_the_same_topology() {
    use fdfsi::discretize::fsi::{CouplingPattern, FsiRestart, FsiState};
    let model = tiny_model();
    let base = vec![0.0; model.solid.num_dofs()];
    let fresh = FsiDiscretization::build(&model, &base, &CouplingPattern::default()).unwrap();
    let own = fresh.coupling_pattern.clone();
    let cells = model.solid.mesh.num_cells();
    let (e, sc) = (0..fresh.coupling.num_elements())
        .flat_map(|e| (0..cells).map(move |c| (e, c)))
        .find(|pair| !own.cells.contains(pair))
        .expect("an element with a solid cell it does not touch");
    let mut carried = own.clone();
    carried.cells.push((e, sc));
    carried.cells.sort_unstable();
    let with = FsiDiscretization::build(&model, &base, &carried).unwrap();
    assert_eq!(with.coupling_pattern, carried);
    let sf = model.solid.displacement_field();
    let (os, ol) = (with.solid_offset(), with.multiplier_offset());
    let multiplier = ol + e * 2 * 2;
    let solid_dofs: Vec<usize> = sf.nodes.cell(sc).iter().map(|&node| os + sf.dof(node, 0)).collect();
    assert!(solid_dofs.iter().all(|&d| with.whole_pattern().find(multiplier, d).is_some()));
    assert!(solid_dofs.iter().any(|&d| fresh.whole_pattern().find(multiplier, d).is_none()));
    assert!(with.nnz() > fresh.nnz());
    // Another topology: the carried cells are dropped.
    let stale = CouplingPattern { topology: carried.topology ^ 1, cells: carried.cells.clone() };
    let without = FsiDiscretization::build(&model, &base, &stale).unwrap();
    assert_eq!(without.coupling_pattern, own);
    assert_eq!(without.nnz(), fresh.nnz());
    // Through a checkpoint's text and back.
    let mut state = FsiState::at_rest(&model);
    state.coupling_pattern = carried.clone();
    let text = serde_json::to_string(&state.to_restart()).unwrap();
    let restart: FsiRestart = serde_json::from_str(&text).unwrap();
    assert_eq!(FsiState::from_restart(&model, 0.0, &restart).unwrap().coupling_pattern, carried);
    // A checkpoint of an earlier build (no such field) starts afresh.
    let old: FsiRestart =
        serde_json::from_str(&text.replace(&format!(",\"coupling_pattern\":{}", serde_json::to_string(&carried).unwrap()), "")).unwrap();
    assert_eq!(old.coupling_pattern, CouplingPattern::default());
}
