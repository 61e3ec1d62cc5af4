//! Symmetry planes of any normal (`[[boundary]] type = "symmetry", normal = [...]`, and the
//! solid's `[[solid.boundary]] type = "symmetry"`; `discretize::symmetry`), by rotation
//! invariance: a problem with its planes normal to coordinate axes (Dirichlet components) and
//! the same problem rotated, its planes inclined (constraint rows), give the same solution rotated
//! back, to round-off: the fluid (3D quarter pipe, a 60-degree sector with one and with two
//! inclined planes, a 2D half channel; the direct and the augmented-Lagrangian solvers), the
//! solid (a membrane and a box on rollers, one node on three planes) and an FSI run (the first
//! steps of model problem 4, coarse).

mod common;
use common::same_rows;
use fdfsi::case::{Case, LinearMethod, MeshSpec, SolidMeshSpec};
use fdfsi::discretize::flow::{solve_steady, Entries, FlowDiscretization, FlowSolution};
use fdfsi::discretize::fsi::{step_with, FsiDiscretization, FsiModel, FsiProblem, FsiState, StepStart};
use fdfsi::discretize::solid::{solve_quasi_static, Lagrangian, LoadStepping, SolidDiscretization, SolidProblem, SolidSolution};
use fdfsi::discretize::symmetry::SymmetryBc;
use fdfsi::discretize::time_scheme::TimeScheme;
use fdfsi::fem::generate::{box_hexahedra, quarter_disc_hexahedra};
use fdfsi::fem::gmsh::AnyMesh;
use fdfsi::fem::mesh::{GeometryOrder, Mesh};
use fdfsi::physics::solid::{Formulation as SolidFormulation, NeoHookeanCompressible, NeoHookeanMixed};
use fdfsi::setup::{build_mesh, flow_problem, solid_mesh, solid_problem};
use fdfsi::solve::linear::LinearSolver;
use fdfsi::solve::newton::NewtonOptions;
use fdfsi::solve::partition::World;
use fdfsi_fem::sparse::{CscMatrix, RowMatrix};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A rotation: `R x`.
type Rotation = [[f64; 3]; 3];

/// The rotation by `degrees` about the unit axis `axis` (Rodrigues).
fn rotation(axis: [f64; 3], degrees: f64) -> Rotation {
    let length = axis.iter().map(|v| v * v).sum::<f64>().sqrt();
    let k = axis.map(|v| v / length);
    let (s, c) = degrees.to_radians().sin_cos();
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let cross = match (i, j) {
                (0, 1) => -k[2],
                (0, 2) => k[1],
                (1, 0) => k[2],
                (1, 2) => -k[0],
                (2, 0) => -k[1],
                (2, 1) => k[0],
                _ => 0.0,
            };
            c * if i == j { 1.0 } else { 0.0 } + s * cross + (1.0 - c) * k[i] * k[j]
        })
    })
}

fn about_z(degrees: f64) -> Rotation {
    rotation([0.0, 0.0, 1.0], degrees)
}

/// `R v` (the first `D` components; `D = 2`: in the plane, `R` about z).
fn apply<const D: usize>(r: &Rotation, v: &[f64; D]) -> [f64; D] {
    std::array::from_fn(|i| (0..D).map(|j| r[i][j] * v[j]).sum())
}

/// `R^T v`.
fn apply_inverse<const D: usize>(r: &Rotation, v: &[f64; D]) -> [f64; D] {
    std::array::from_fn(|i| (0..D).map(|j| r[j][i] * v[j]).sum())
}

fn cases_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("cases")
}

/// Boundary `name` of the case made a symmetry plane of normal `normal` (or of `normal_axis`).
fn set_plane(case: &mut Case, name: &str, normal: Option<Vec<f64>>, axis: Option<usize>) {
    let b = case.boundary.iter_mut().find(|b| b.name == name).unwrap_or_else(|| panic!("boundary {name}"));
    b.normal = normal;
    b.normal_axis = axis;
}

/// Unit axis `a` rotated by `r`, as a case's normal (the first `d` entries).
fn rotated_axis(r: &Rotation, a: usize, d: usize) -> Vec<f64> {
    let e: [f64; 3] = std::array::from_fn(|i| if i == a { 1.0 } else { 0.0 });
    apply(r, &e)[..d].to_vec()
}

/// The steady flow of `case` on its mesh with the points mapped by `map`: the discretisation,
/// the solution and the Krylov iterations of its solve.
fn solve_flow<const D: usize>(case: &Case, map: impl Fn(&[f64; D]) -> [f64; D]) -> (FlowDiscretization<D>, FlowSolution) {
    let mut mesh: Mesh<D> = build_mesh(case, &cases_dir()).unwrap().into_dim::<D>().expect("the case's dimension");
    mesh.points.iter_mut().for_each(|p| *p = map(p));
    let problem = flow_problem(case, &mesh, &cases_dir()).unwrap();
    let disc = FlowDiscretization::build_for(mesh, &problem, Entries::Whole).unwrap();
    let mut solver = case.solver.linear_solver(false, case.physics.formulation);
    let solution = solve_steady(&disc, &problem, solver.as_mut(), &case.solver.newton).unwrap();
    (disc, solution)
}

/// The largest differences of the velocity and of the pressure (its cell values and its
/// gradients) of solution `b`, on the mesh of `a` rotated by `r`, rotated back, from `a`'s,
/// relative to their largest values in `a`.
fn flow_difference<const D: usize>(a: &(FlowDiscretization<D>, FlowSolution), b: &(FlowDiscretization<D>, FlowSolution), r: &Rotation) -> (f64, f64) {
    let (disc, xa, xb) = (&a.0, &a.1, &b.1);
    assert_eq!(disc.num_dofs(), b.0.num_dofs());
    let (mut du, mut umax, mut dp, mut pmax) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for node in 0..disc.velocity_nodes.len() {
        let (ua, ub) = (xa.velocity(disc, node), apply_inverse(r, &xb.velocity(&b.0, node)));
        for k in 0..D {
            du = du.max((ua[k] - ub[k]).abs());
            umax = umax.max(ua[k].abs());
        }
    }
    for c in 0..disc.mesh.num_cells() {
        let (pa, pb) = (xa.pressure_dofs(disc, c), xb.pressure_dofs(&b.0, c));
        let ga: [f64; D] = std::array::from_fn(|k| pa[1 + k]);
        let gb = apply_inverse(r, &std::array::from_fn::<f64, D, _>(|k| pb[1 + k]));
        dp = dp.max((pa[0] - pb[0]).abs());
        pmax = pmax.max(pa[0].abs());
        for k in 0..D {
            dp = dp.max((ga[k] - gb[k]).abs());
            pmax = pmax.max(ga[k].abs());
        }
    }
    (du / umax, dp / pmax)
}

/// The Krylov iterations of a steady solve, summed.
fn krylov(s: &FlowSolution) -> usize {
    s.newton.krylov_iterations.iter().sum()
}

/// The quarter pipe of cases/quarter-pipe-3d-stokes.toml with the linear `method`, tight
/// tolerances (agreement to round-off).
fn quarter_pipe(method: LinearMethod) -> Case {
    let mut case = Case::read(&cases_dir().join("quarter-pipe-3d-stokes.toml")).unwrap();
    case.solver.linear.method = method;
    case.solver.linear.krylov_tolerance = 1e-13;
    case.solver.newton.abs_tol = 1e-13;
    case.solver.newton.rel_tol = 1e-14;
    case
}

/// The AL solver's Krylov iterations on the quarter pipe at the case's tolerances (Krylov 1e-8)
/// are those of the planes x = 0 and y = 0 with the planes inclined (turned by 30 degrees), and
/// with one plane inclined (a 60-degree sector turned by -60 degrees, against the sector turned
/// by -30 degrees, both planes inclined): the constraint rows count as Dirichlet rows in the
/// preconditioner's groups at Dirichlet boundaries.
#[test]
fn inclined_planes_cost_the_al_solver_no_krylov_iterations() {
    let case = Case::read(&cases_dir().join("quarter-pipe-3d-stokes.toml")).unwrap();
    assert_eq!(case.solver.linear.method, LinearMethod::AugmentedLagrangian);
    let iterations = |case: &Case, map: &dyn Fn(&[f64; 3]) -> [f64; 3]| solve_flow::<3>(case, map).1.newton.krylov_iterations;
    let plain = iterations(&case, &|p| *p);
    let r = about_z(30.0);
    let mut turned = case.clone();
    set_plane(&mut turned, "symmetry_x", Some(rotated_axis(&r, 0, 3)), None);
    set_plane(&mut turned, "symmetry_y", Some(rotated_axis(&r, 1, 3)), None);
    let inclined = iterations(&turned, &|p| apply(&r, p));
    let sector = |p: &[f64; 3]| {
        let (radius, angle) = (p[0].hypot(p[1]), p[1].atan2(p[0]) * 2.0 / 3.0);
        [radius * angle.cos(), radius * angle.sin(), p[2]]
    };
    let (r30, r60) = (about_z(-30.0), about_z(-60.0));
    let mut both = case.clone();
    set_plane(&mut both, "symmetry_x", Some(rotated_axis(&about_z(30.0), 1, 3)), None);
    set_plane(&mut both, "symmetry_y", Some(rotated_axis(&r30, 1, 3)), None);
    let sector_both = iterations(&both, &|p| apply(&r30, &sector(p)));
    let mut one = case.clone();
    set_plane(&mut one, "symmetry_x", None, Some(1));
    set_plane(&mut one, "symmetry_y", Some(rotated_axis(&r60, 1, 3)), None);
    let sector_one = iterations(&one, &|p| apply(&r60, &sector(p)));
    println!(
        "Krylov iterations per Newton step: quarter pipe {plain:?}, turned (two planes inclined) {inclined:?}; sector, one plane inclined {sector_one:?}, two {sector_both:?}"
    );
    assert_eq!(plain.len(), inclined.len());
    for (a, b) in plain.iter().zip(&inclined) {
        assert!(b.abs_diff(*a) <= 1, "{plain:?} against {inclined:?}");
    }
    assert_eq!(sector_one.len(), sector_both.len());
    for (a, b) in sector_one.iter().zip(&sector_both) {
        assert!(b.abs_diff(*a) <= 1, "{sector_one:?} against {sector_both:?}");
    }
}

/// The quarter pipe (planes x = 0 and y = 0) against the same pipe turned by 30 degrees about
/// z, both planes inclined (the axis on both: only the velocity along it free); and a sector of
/// 60 degrees (the quarter's angles scaled by 2/3: planes y = 0 and at 60 degrees) against
/// itself turned by -30 degrees (both planes inclined) and by -60 degrees (its plane at 60
/// degrees then y = 0, given as `normal_axis`, the other inclined). Direct and AL solvers:
/// velocity and pressure equal to 1e-11 relative (measured: 1.1e-14 and 9.2e-13 at worst).
#[test]
fn a_turned_quarter_pipe_flows_as_the_quarter_pipe() {
    for method in [LinearMethod::Direct, LinearMethod::AugmentedLagrangian] {
        let case = quarter_pipe(method);
        let plain = solve_flow::<3>(&case, |p| *p);
        let r = about_z(30.0);
        let mut turned = case.clone();
        set_plane(&mut turned, "symmetry_x", Some(rotated_axis(&r, 0, 3)), None);
        set_plane(&mut turned, "symmetry_y", Some(rotated_axis(&r, 1, 3)), None);
        let rotated = solve_flow::<3>(&turned, |p| apply(&r, p));
        let (du, dp) = flow_difference(&plain, &rotated, &r);
        println!(
            "{method:?}: quarter pipe turned by 30 degrees: velocity {du:.2e}, pressure {dp:.2e}; Krylov iterations {} (planes x = 0, y = 0) and {} (inclined)",
            krylov(&plain.1),
            krylov(&rotated.1)
        );
        assert!(du < 1e-11 && dp < 1e-11, "{method:?}: {du:e} {dp:e}");
        // The sector of 60 degrees: its plane at 60 degrees the quarter's x = 0.
        let sector = |p: &[f64; 3]| {
            let (radius, angle) = (p[0].hypot(p[1]), p[1].atan2(p[0]) * 2.0 / 3.0);
            [radius * angle.cos(), radius * angle.sin(), p[2]]
        };
        let r60 = about_z(60.0);
        let mut one = case.clone();
        set_plane(&mut one, "symmetry_x", Some(rotated_axis(&r60, 1, 3)), None);
        let base = solve_flow::<3>(&one, sector);
        for degrees in [-30.0, -60.0] {
            let r = about_z(degrees);
            let mut turned = case.clone();
            set_plane(&mut turned, "symmetry_y", Some(rotated_axis(&r, 1, 3)), None);
            if degrees == -60.0 {
                set_plane(&mut turned, "symmetry_x", None, Some(1));
            } else {
                set_plane(&mut turned, "symmetry_x", Some(rotated_axis(&about_z(60.0 + degrees), 1, 3)), None);
            }
            let rotated = solve_flow::<3>(&turned, |p| apply(&r, &sector(p)));
            let (du, dp) = flow_difference(&base, &rotated, &r);
            println!(
                "{method:?}: 60-degree sector (one plane inclined) against it turned by {degrees} degrees ({} inclined): velocity {du:.2e}, pressure {dp:.2e}; Krylov iterations {} and {}",
                if degrees == -60.0 { "one" } else { "both" },
                krylov(&base.1),
                krylov(&rotated.1)
            );
            assert!(du < 1e-11 && dp < 1e-11, "{method:?}, {degrees}: {du:e} {dp:e}");
        }
    }
}

/// A 2D half channel (Navier-Stokes, Re = 20; symmetry line y = 0, wall y = 1, parabolic inflow,
/// free outlet) turned by 25 degrees, its symmetry line and inflow turned with it: the same flow
/// to 1e-11, with the direct and the AL solvers.
#[test]
fn a_turned_half_channel_flows_as_the_half_channel() {
    let text = |inflow: [&str; 2], bottom: &str| {
        format!(
            "title = \"half channel\"\n[mesh]\nkind = \"channel\"\nlength = 4.0\nheight = 1.0\nn = [16, 4]\n[physics]\nformulation = \"plane\"\n\
             model = \"navier-stokes\"\n[fluid]\ndensity = 1.0\nviscosity = 0.05\n[[boundary]]\nname = \"inlet\"\ntype = \"velocity\"\n\
             value = [\"{}\", \"{}\"]\n[[boundary]]\nname = \"top\"\ntype = \"no-slip\"\n[[boundary]]\nname = \"bottom\"\ntype = \"symmetry\"\n\
             {bottom}\n[[boundary]]\nname = \"outlet\"\ntype = \"free\"\n[solver.newton]\nabs_tol = 1e-13\nrel_tol = 1e-14\n\
             [solver.linear]\nkrylov_tolerance = 1e-13\n",
            inflow[0], inflow[1]
        )
    };
    let degrees = 25.0f64;
    let r = about_z(degrees);
    let (s, c) = degrees.to_radians().sin_cos();
    // Across the channel: eta = -s x + c y; the inflow (1 - eta^2) along (c, s).
    let eta = format!("(-({s:.17}) * x + {c:.17} * y)");
    let f = format!("(1 - {eta}^2)");
    let turned_inflow = [format!("{c:.17} * {f}"), format!("{s:.17} * {f}")];
    let normal = format!("normal = [{:.17}, {:.17}]", -s, c);
    for method in [LinearMethod::Direct, LinearMethod::AugmentedLagrangian] {
        let read = |t: String| {
            let mut case = Case::from_toml_str(&t, "half-channel.toml").unwrap();
            case.solver.linear.method = method;
            case
        };
        let plain = solve_flow::<2>(&read(text(["1 - y^2", "0"], "normal_axis = 1")), |p| *p);
        let rotated = solve_flow::<2>(&read(text([&turned_inflow[0], &turned_inflow[1]], &normal)), |p| apply(&r, p));
        let (du, dp) = flow_difference(&plain, &rotated, &r);
        println!(
            "{method:?}: half channel turned by 25 degrees: velocity {du:.2e}, pressure {dp:.2e}; Newton {} and {}, Krylov iterations {} and {}",
            plain.1.newton.iterations,
            rotated.1.newton.iterations,
            krylov(&plain.1),
            krylov(&rotated.1)
        );
        assert!(du < 1e-11 && dp < 1e-11, "{method:?}: {du:e} {dp:e}");
        assert_eq!(plain.1.newton.iterations, rotated.1.newton.iterations);
    }
}

/// Solves `problem` on `mesh` (three load steps, updated Lagrangian) with the direct LU.
fn solve_solid(mesh: Mesh<3>, problem: &SolidProblem<3>) -> (SolidDiscretization<3>, SolidSolution) {
    let disc = SolidDiscretization::build_for(mesh, problem).unwrap();
    let newton = NewtonOptions { abs_tol: 1e-13, rel_tol: 1e-14, ..Default::default() };
    let stepping = LoadStepping::uniform(Lagrangian::Updated, 3);
    let solution = solve_quasi_static(&disc, problem, &stepping, &mut fdfsi::solve::linear::FaerLu::default(), &newton).unwrap();
    (disc, solution)
}

/// The largest difference of the displacement (and the pressure's cell values and gradients,
/// with a pressure field) of `b`, on the mesh of `a` rotated by `r`, rotated back, from `a`'s,
/// relative to the largest displacement; and that displacement.
fn solid_difference(a: &(SolidDiscretization<3>, SolidSolution), b: &(SolidDiscretization<3>, SolidSolution), r: &Rotation) -> (f64, f64) {
    let (disc, xa, xb) = (&a.0, &a.1.x, &b.1.x);
    let (mut diff, mut umax) = (0.0f64, 0.0f64);
    for node in 0..disc.nodes_x0.len() {
        let (ua, ub) = (disc.displacement(xa, node), apply_inverse(r, &b.0.displacement(xb, node)));
        for k in 0..3 {
            diff = diff.max((ua[k] - ub[k]).abs());
            umax = umax.max(ua[k].abs());
        }
    }
    let mut pressure = 0.0f64;
    if disc.mixed {
        let pf = disc.pressure_field();
        let (mut dp, mut pmax) = (0.0f64, 0.0f64);
        for c in 0..disc.mesh.num_cells() {
            let dofs: [f64; 4] = std::array::from_fn(|k| xa[pf.dof(c * 4 + k, 0)]);
            let other: [f64; 4] = std::array::from_fn(|k| xb[pf.dof(c * 4 + k, 0)]);
            let g = apply_inverse(r, &[other[1], other[2], other[3]]);
            for (k, v) in [other[0], g[0], g[1], g[2]].iter().enumerate() {
                dp = dp.max((dofs[k] - v).abs());
                pmax = pmax.max(dofs[k].abs());
            }
        }
        pressure = dp / pmax;
    }
    (diff.max(pressure * umax) / umax, umax)
}

/// The membrane of model problem 4 (the quarter disc, incompressible neo-Hookean, G = 1000,
/// clamped at the wall, rollers on x = 0 and y = 0) under a follower pressure, against itself
/// turned by 30 degrees about z on inclined rollers; and a box on rollers on three faces (a
/// corner on all three: held by three constraint rows) under a dead traction, compressible,
/// against itself turned about the axis (1, 2, 3) by 40 degrees, its traction turned with it:
/// the displacements (and the membrane's pressure) equal to 1e-11.
#[test]
fn a_turned_solid_on_rollers_deforms_as_the_solid() {
    let material = Arc::new(NeoHookeanMixed::incompressible(1000.0));
    let membrane = |r: &Rotation, rollers: bool| {
        let mut mesh = quarter_disc_hexahedra(1.0, 1.975, 2.025, 3, 2, 1);
        mesh.points.iter_mut().for_each(|p| *p = apply(r, p));
        let mut problem = SolidProblem::new(SolidFormulation::ThreeD, material.clone())
            .with_displacement("wall", &[0, 1, 2], |_, _| [0.0; 3])
            .with_pressure("zmin", |load| load);
        for (name, a) in [("symmetry_x", 0), ("symmetry_y", 1)] {
            problem = match rollers {
                false => problem.with_displacement(name, &[a], |_, _| [0.0; 3]),
                true => problem.with_symmetry(SymmetryBc::new(name, apply(r, &std::array::from_fn(|i| if i == a { 1.0 } else { 0.0 }))).unwrap()),
            };
        }
        solve_solid(mesh, &problem)
    };
    let plain = membrane(&about_z(0.0), false);
    let r = about_z(30.0);
    let turned = membrane(&r, true);
    let (diff, umax) = solid_difference(&plain, &turned, &r);
    println!("membrane turned by 30 degrees: displacement and pressure {diff:.2e} (largest displacement {umax:.4})");
    assert!(diff < 1e-11 && umax > 0.05, "{diff:e}, {umax}");
    let compressible = Arc::new(NeoHookeanCompressible::from_shear_bulk(1.0, 5.0));
    let traction = [0.1, 0.05, -0.1];
    let block = |r: &Rotation, rollers: bool| {
        let mut mesh = box_hexahedra(0.0, 1.0, 0.0, 1.0, 0.0, 0.5, 2, 2, 1, GeometryOrder::Quadratic);
        mesh.points.iter_mut().for_each(|p| *p = apply(r, p));
        let t = apply(r, &traction);
        let mut problem = SolidProblem::new(SolidFormulation::ThreeD, compressible.clone()).with_traction("zmax", move |_, load| t.map(|v| v * load));
        for (name, a) in [("xmin", 0), ("ymin", 1), ("zmin", 2)] {
            problem = match rollers {
                false => problem.with_displacement(name, &[a], |_, _| [0.0; 3]),
                true => problem.with_symmetry(SymmetryBc::new(name, apply(r, &std::array::from_fn(|i| if i == a { 1.0 } else { 0.0 }))).unwrap()),
            };
        }
        solve_solid(mesh, &problem)
    };
    let plain = block(&about_z(0.0), false);
    let r = rotation([1.0, 2.0, 3.0], 40.0);
    let turned = block(&r, true);
    let (diff, umax) = solid_difference(&plain, &turned, &r);
    println!("box turned by 40 degrees about (1, 2, 3): displacement {diff:.2e} (largest displacement {umax:.4})");
    assert!(diff < 1e-11 && umax > 0.01, "{diff:e}, {umax}");
}

/// What the FSI comparison reads of each step: the centre's displacement along z, the fluid
/// velocities (rotated back) and pressures, the solid's displacement (rotated back), the Newton
/// iterations and the Krylov iterations.
struct FsiSteps {
    centre: Vec<f64>,
    velocity: Vec<Vec<[f64; 3]>>,
    pressure: Vec<Vec<f64>>,
    displacement: Vec<Vec<[f64; 3]>>,
    newton: Vec<usize>,
    krylov: Vec<usize>,
    /// The multiplier modes removed, and the nodes on symmetry planes of any normal.
    kernel: Vec<usize>,
    constrained_nodes: Vec<usize>,
}

/// Model problem 4 on the coarse meshes of tests/cases.rs, fluid and solid meshes turned by `r`
/// about z, the symmetry planes of both given as `normal`s (turned) when `inclined`: the case
/// (with the linear `method` and tight tolerances) and the FSI model.
fn model_problem_4_model(r: &Rotation, inclined: bool, method: LinearMethod) -> (Case, FsiModel<3>) {
    let dir = cases_dir();
    let mut case = Case::read(&dir.join("model-problem-4.toml")).unwrap();
    case.mesh = Some(MeshSpec::Pipe { radius: 1.0, length: 4.0, n_radial: 4, n_axial: 6, quarter: true });
    let solid = case.solid.first_mut().unwrap();
    solid.mesh = SolidMeshSpec::QuarterDisc { radius: 1.0, z: [1.975, 2.025], n_core: 3, n_ring: 2, n_layers: 1 };
    case.solver.linear.method = method;
    case.solver.linear.krylov_tolerance = 1e-12;
    case.solver.newton.abs_tol = 1e-12;
    if inclined {
        for (name, a) in [("symmetry_x", 0), ("symmetry_y", 1)] {
            set_plane(&mut case, name, Some(rotated_axis(r, a, 3)), None);
            let b = case.solid[0].boundary.iter_mut().find(|b| b.name == name).unwrap();
            b.kind = fdfsi::case::SolidBoundaryType::Symmetry;
            b.value.clear();
            b.components = None;
            b.normal = Some(rotated_axis(r, a, 3));
        }
    }
    case.validate("model-problem-4.toml").unwrap();
    let Ok(AnyMesh::D3(mut fluid)) = build_mesh(&case, &dir) else { panic!("3D") };
    fluid.points.iter_mut().for_each(|p| *p = apply(r, p));
    let mut solid_mesh = solid_mesh::<3>(&case, &dir).unwrap();
    solid_mesh.mesh.points.iter_mut().for_each(|p| *p = apply(r, p));
    let spec = case.first_solid().unwrap();
    let problem = FsiProblem {
        fluid: flow_problem(&case, &fluid, &dir).unwrap(),
        solid: solid_problem::<3>(&case, solid_mesh.cell_body, false).unwrap(),
        surface: case.solid_surface().unwrap(),
        adapt: fdfsi::setup::adapt_options(spec),
    };
    assert_eq!((problem.fluid.symmetry.len(), problem.solid.symmetry.len()), if inclined { (2, 2) } else { (0, 0) });
    let model = FsiModel::new(problem, &fluid, solid_mesh.mesh).unwrap().with_multiplier(spec.multiplier).with_covered_fluid(spec.covered_fluid);
    (case, model)
}

/// The first `steps` steps of [`model_problem_4_model`].
fn model_problem_4(r: &Rotation, inclined: bool, method: LinearMethod, steps: usize) -> FsiSteps {
    let (case, model) = model_problem_4_model(r, inclined, method);
    let mut solver: Box<dyn LinearSolver> = case.solver.linear_solver(true, case.physics.formulation);
    let centre = model.solid.node_near(&apply(r, &[0.0, 0.0, 2.0]));
    let mut state = FsiState::at_rest(&model);
    let mut out = FsiSteps {
        centre: vec![],
        velocity: vec![],
        pressure: vec![],
        displacement: vec![],
        newton: vec![],
        krylov: vec![],
        kernel: vec![],
        constrained_nodes: vec![],
    };
    let dt = case.time.as_ref().unwrap().dt;
    for _ in 0..steps {
        let (next, step) = step_with(&model, &state, dt, TimeScheme::Euler, solver.as_mut(), &case.solver.newton).unwrap();
        state = next;
        let disc = &step.disc;
        let vel = disc.flow.velocity_field();
        out.velocity.push((0..disc.flow.velocity_nodes.len()).map(|n| apply_inverse(r, &std::array::from_fn(|a| step.x[vel.dof(n, a)]))).collect());
        let pf = disc.flow.pressure_field();
        out.pressure.push((0..disc.flow.mesh.num_cells()).map(|c| step.x[pf.dof(c * 4, 0)]).collect());
        out.displacement.push((0..model.solid.nodes_x0.len()).map(|n| apply_inverse(r, &model.solid.displacement(&state.solid_x, n))).collect());
        out.centre.push(model.solid.displacement(&state.solid_x, centre)[2]);
        out.newton.push(step.report.newton.iterations);
        out.krylov.push(step.report.newton.krylov_iterations.iter().sum());
        out.kernel.push(disc.kernel.len());
        out.constrained_nodes.push(disc.normal_constraints.num_nodes());
    }
    out
}

/// The largest difference of `b` from `a`, relative to the largest value of `a`.
fn relative(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
}

/// Model problem 4 (coarse, 3 steps) against itself turned by 30 degrees about z, fluid and
/// solid, the symmetry planes of both inclined: the adapted meshes alike, the centre's
/// displacement, the solid's displacement, the fluid's velocity and pressure equal to 1e-11
/// relative at every step with the direct solver (1e-10 with the AL solver), in the same Newton
/// iterations.
#[test]
fn a_turned_model_problem_4_moves_as_model_problem_4() {
    for method in [LinearMethod::Direct, LinearMethod::AugmentedLagrangian] {
        let plain = model_problem_4(&about_z(0.0), false, method, 3);
        let r = about_z(30.0);
        let turned = model_problem_4(&r, true, method, 3);
        println!("{method:?}: centre displacement {:?} and {:?}", plain.centre, turned.centre);
        println!(
            "{method:?}: Newton iterations {:?} and {:?}, Krylov iterations {:?} and {:?}",
            plain.newton, turned.newton, plain.krylov, turned.krylov
        );
        println!(
            "{method:?}: multiplier modes removed {:?} and {:?}; nodes on inclined planes {:?}",
            plain.kernel, turned.kernel, turned.constrained_nodes
        );
        assert_eq!(plain.newton, turned.newton, "{method:?}");
        assert_eq!(plain.kernel, turned.kernel, "{method:?}");
        assert!(
            plain.constrained_nodes.iter().all(|&n| n == 0) && turned.constrained_nodes.iter().all(|&n| n > 100),
            "{:?}",
            turned.constrained_nodes
        );
        let flat = |v: &[[f64; 3]]| v.iter().flatten().copied().collect::<Vec<f64>>();
        for k in 0..3 {
            let differences = [
                ("centre", relative(&plain.centre[k..=k], &turned.centre[k..=k])),
                ("solid displacement", relative(&flat(&plain.displacement[k]), &flat(&turned.displacement[k]))),
                ("fluid velocity", relative(&flat(&plain.velocity[k]), &flat(&turned.velocity[k]))),
                ("fluid pressure", relative(&plain.pressure[k], &turned.pressure[k])),
            ];
            println!("{method:?}, step {}: {differences:?}", k + 1);
            // The AL solver's Krylov solves stop at their tolerance, so its iterates differ by
            // more than round-off (measured 4.8e-13; the direct solver 1e-13).
            let tol = if method == LinearMethod::Direct { 1e-11 } else { 1e-10 };
            for (what, d) in differences {
                assert!(d < tol, "{method:?}, step {}: {what} {d:e}", k + 1);
            }
        }
    }
}

/// Each rank's rows of a partitioned assembly (2 and 3 ranks) with inclined symmetry planes are
/// the whole assembly's rows bit for bit, their nodes' rows combined alike: the turned quarter
/// pipe (flow) and the first step of the turned model problem 4 (FSI: the fluid's and the
/// solid's planes).
#[test]
fn each_ranks_rows_with_inclined_planes_are_the_whole_assemblys() {
    let r = about_z(30.0);
    let mut case = quarter_pipe(LinearMethod::Direct);
    set_plane(&mut case, "symmetry_x", Some(rotated_axis(&r, 0, 3)), None);
    set_plane(&mut case, "symmetry_y", Some(rotated_axis(&r, 1, 3)), None);
    let mut mesh: Mesh<3> = build_mesh(&case, &cases_dir()).unwrap().into_dim::<3>().unwrap();
    mesh.points.iter_mut().for_each(|p| *p = apply(&r, p));
    let problem = flow_problem(&case, &mesh, &cases_dir()).unwrap();
    let whole = FlowDiscretization::build_for(mesh.clone(), &problem, Entries::Whole).unwrap();
    assert!(whole.normal_constraints().num_nodes() > 50);
    let n = whole.num_dofs();
    let mut x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
    let constrained = whole.impose_dirichlet(&problem, 0.0, &mut x).unwrap();
    let (mut k, mut rhs) = (CscMatrix::zeros(whole.whole_pattern()), vec![0.0; n]);
    whole.assemble_system(&problem, &x, &x, 0.0, &constrained, &mut k, &mut rhs).unwrap();
    for size in [2, 3] {
        let mut covered = 0;
        for rank in 0..size {
            let disc = FlowDiscretization::build_for(mesh.clone(), &problem, Entries::Rows(World { rank, size })).unwrap();
            let part = disc.rows().unwrap();
            let (mut a, mut rhs_rows) = (RowMatrix::zeros(&part.pattern), vec![0.0; part.pattern.rows.len()]);
            disc.assemble_rows(&problem, &x, &x, 0.0, &constrained, &mut a, &mut rhs_rows).unwrap();
            covered += same_rows(&part.partition, &a, &rhs_rows, &k, &rhs, &format!("flow, rank {rank} of {size}"));
        }
        assert_eq!(Some(covered), whole.nnz());
    }
    let (case, model) = model_problem_4_model(&r, true, LinearMethod::Direct);
    let state = FsiState::at_rest(&model);
    let start = StepStart::new(&model, &state, case.time.as_ref().unwrap().dt).unwrap();
    let (disc, input) = (&start.disc, start.input(&state));
    let n = disc.num_dofs();
    let mut x: Vec<f64> =
        start.x.iter().enumerate().map(|(i, &v)| if start.constrained[i] { v } else { 1e-3 * ((i + 1) as f64 * 0.37).sin() }).collect();
    disc.normal_constraints.project(&mut x);
    let (mut k, mut rhs) = (CscMatrix::zeros(disc.whole_pattern()), vec![0.0; n]);
    disc.assemble(&model, &input, &x, &start.constrained, &mut k, &mut rhs).unwrap();
    for size in [2, 3] {
        let mut covered = 0;
        for rank in 0..size {
            let rows = FsiDiscretization::build_with(&model, &start.geometry, &state.coupling_pattern, Entries::Rows(World { rank, size })).unwrap();
            let part = rows.rows().unwrap();
            let (mut a, mut rhs_rows) = (RowMatrix::zeros(&part.pattern), vec![0.0; part.pattern.rows.len()]);
            rows.assemble_rows(&model, &input, &x, &start.constrained, &mut a, &mut rhs_rows).unwrap();
            covered += same_rows(&part.partition, &a, &rhs_rows, &k, &rhs, &format!("FSI, rank {rank} of {size}"));
        }
        assert_eq!(Some(covered), disc.nnz());
    }
}
