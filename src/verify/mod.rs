//! Convergence studies on manufactured solutions (`fdfsi verify`).
//!
//! A study solves one problem on a sequence of refined meshes, records an error norm per mesh,
//! and reports the observed rate `log(e_{k-1}/e_k) / log(h_{k-1}/h_k)` of the last two meshes
//! beside the expected one. The tests run the same code and assert the rates.
//!
//! | study | mesh | boundary conditions | expected rates (u L2, u H1, p L2) |
//! |---|---|---|---|
//! | `stokes-plane` | unit square, triangles | velocity on three sides, traction on `right` | 3, 2, 2 |
//! | `stokes-axisymmetric` | `(z, r)` in unit square, axis at `r = 0` | `u_r = 0` on the axis, velocity on `left`/`top`, traction on `right` | 3, 2, 2 |
//! | `stokes-3d` | unit cube, tetrahedra | velocity on five faces, traction on `xmax` | 3, 2, 2 |
//!
//! Time convergence (`time-euler`, `time-bdf2`): Navier-Stokes with `u = (g(t) y (1 - y), 0)`,
//! `p = 0`, `g(t) = sin(2 t)`, `rho = eta = 1`, body force `f_x = g'(t) y (1 - y) + 2 g(t)`.
//! The field lies in the P2 space and `u . grad u = 0`, so the error at `T = 1` is the time
//! discretisation's alone; `h` is the time step, expected rates 1 (Euler) and 2 (BDF2).
//!
//! Solid dynamics (`solid-dynamics-euler`, `solid-dynamics-bdf2`): a Saint Venant-Kirchhoff
//! square (`mu = 1`, `lambda = 1.5`, `rho_0 = 1`, plane strain) in the affine motion
//! `u = s(t) A X`, `s(t) = 1 - cos(2 pi t)` (from rest), `A = [[0.05, 0.02], [-0.03, 0.04]]`:
//! its stress is uniform, so the body force is the inertia alone, `b = rho_0 s''(t) A X`; the
//! displacement on `left` and `bottom`, the traction `P N` on `right` and `top`. The motion lies
//! in the Q2 space: the displacement error at `T = 0.5` is the time discretisation's alone.

pub mod manufactured;
pub mod solid_exact;
pub mod womersley;

use crate::discretize::flow::{flow_errors, solve_steady, DirichletBc, ExactFlow, FlowDiscretization, FlowError, FlowProblem, TractionBc};
use crate::physics::fluid::{FluidParams, Formulation, Stabilization};
use crate::solve::linear::FaerLu;
use crate::solve::newton::NewtonOptions;
use fdfsi_fem::generate::{box_tetrahedra, rectangle_triangles, DiagonalPattern};
use fdfsi_fem::mesh::Mesh;
use manufactured::{AxisymmetricStokes, Manufactured, PlaneStokes, Stokes3d};
use serde::Serialize;
use std::sync::Arc;

/// One convergence study of one quantity.
#[derive(Clone, Debug, Serialize)]
pub struct Study {
    pub name: String,
    pub quantity: String,
    pub expected_rate: f64,
    pub observed_rate: f64,
    pub h: Vec<f64>,
    pub errors: Vec<f64>,
}

impl Study {
    fn new(name: &str, quantity: &str, expected_rate: f64, h: &[f64], errors: Vec<f64>) -> Self {
        Study {
            name: name.to_string(),
            quantity: quantity.to_string(),
            expected_rate,
            observed_rate: observed_rate(h, &errors),
            h: h.to_vec(),
            errors,
        }
    }
}

/// Rate between the last two entries.
pub fn observed_rate(h: &[f64], e: &[f64]) -> f64 {
    let n = h.len();
    if n < 2 {
        return f64::NAN;
    }
    (e[n - 2] / e[n - 1]).ln() / (h[n - 2] / h[n - 1]).ln()
}

/// The JSON document `fdfsi verify --json` writes: the convergence studies, and the exact states
/// reproduced to round-off.
#[derive(Clone, Debug, Serialize)]
pub struct VerifyReport {
    pub studies: Vec<Study>,
    pub checks: Vec<solid_exact::ExactnessCheck>,
}

/// Mesh sizes of a study.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Effort {
    /// Small meshes, seconds (the test suite).
    Quick,
    /// One more refinement.
    Full,
}

/// The steady Stokes problem whose solution is `exact`: its body force, its velocity on the
/// `dirichlet` boundaries (with the listed components) and its traction on the `traction`
/// boundaries; stress form of the viscous term.
pub fn manufactured_problem<const D: usize>(
    formulation: Formulation,
    exact: Arc<dyn Manufactured<D>>,
    dirichlet: &[(&str, Vec<usize>)],
    traction: &[&str],
) -> FlowProblem<D> {
    let ex = exact.clone();
    FlowProblem {
        formulation,
        params: FluidParams {
            viscosity: exact.viscosity(),
            density: 1.0,
            inv_dt: 0.0,
            convection: false,
            convective_form: Default::default(),
            viscous_form: Default::default(),
            stabilization: Default::default(),
        },
        body_force: Some(Arc::new(move |x: &[f64; D], _t| ex.body_force(x))),
        dirichlet: dirichlet
            .iter()
            .map(|(name, comps)| {
                let ex = exact.clone();
                DirichletBc { boundary: name.to_string(), components: comps.clone(), value: Arc::new(move |x: &[f64; D], _t| ex.velocity(x)) }
            })
            .collect(),
        traction: traction
            .iter()
            .map(|name| {
                let ex = exact.clone();
                TractionBc { boundary: name.to_string(), traction: Arc::new(move |x: &[f64; D], n: &[f64; D], _t| ex.traction(x, n)) }
            })
            .collect(),
        pin_pressure: false,
        windkessel: Vec::new(),
        backflow: Vec::new(),
        symmetry: Vec::new(),
    }
}

/// The boundaries of the `stokes-3d` study on the unit cube: velocity on five faces (all
/// components), traction on `xmax`.
const STOKES_3D_VELOCITY: [&str; 5] = ["xmin", "ymin", "ymax", "zmin", "zmax"];
const STOKES_3D_TRACTION: [&str; 1] = ["xmax"];

/// The `stokes-3d` verification problem ([`Stokes3d`] with `eta = 1`, boundaries as in
/// [`stokes_3d`]), for `box_tetrahedra` on the unit cube: used by the benchmarks of the solver.
pub fn stokes_3d_problem() -> FlowProblem<3> {
    let dirichlet: Vec<(&str, Vec<usize>)> = STOKES_3D_VELOCITY.iter().map(|&f| (f, vec![0, 1, 2])).collect();
    manufactured_problem(Formulation::ThreeD, Arc::new(Stokes3d { eta: 1.0 }), &dirichlet, &STOKES_3D_TRACTION)
}

/// Solves a Stokes manufactured problem on `mesh` and returns the error norms and the largest
/// cell divergence.
pub fn stokes_errors<const D: usize>(
    mesh: Mesh<D>,
    formulation: Formulation,
    exact: Arc<dyn Manufactured<D>>,
    dirichlet: &[(&str, Vec<usize>)],
    traction: &[&str],
) -> Result<(crate::discretize::flow::FlowErrors, usize), FlowError> {
    let disc = FlowDiscretization::build(mesh, formulation)?;
    let problem = manufactured_problem(formulation, exact.clone(), dirichlet, traction);
    let mut lu = FaerLu::default();
    let sol = solve_steady(&disc, &problem, &mut lu, &NewtonOptions::default())?;
    let (u, g, p) = (|x: &[f64; D]| exact.velocity(x), |x: &[f64; D]| exact.gradient(x), |x: &[f64; D]| exact.pressure(x));
    let errors = flow_errors(&disc, formulation, &sol.x, &ExactFlow { velocity: &u, gradient: &g, pressure: &p }, 8)?;
    Ok((errors, disc.num_dofs()))
}

/// Result of one Stokes convergence run: three studies and the divergence check.
pub struct StokesRun {
    pub studies: Vec<Study>,
    /// Largest `|int_K div u_h|` over all cells and meshes.
    pub max_cell_divergence: f64,
    pub dofs: Vec<usize>,
}

fn three_studies(name: &str, h: &[f64], errs: &[crate::discretize::flow::FlowErrors]) -> Vec<Study> {
    vec![
        Study::new(name, "velocity_l2", 3.0, h, errs.iter().map(|e| e.velocity_l2).collect()),
        Study::new(name, "velocity_h1", 2.0, h, errs.iter().map(|e| e.velocity_h1).collect()),
        Study::new(name, "pressure_l2", 2.0, h, errs.iter().map(|e| e.pressure_l2).collect()),
    ]
}

fn run_levels<const D: usize>(
    name: &str,
    levels: &[usize],
    mesh_of: impl Fn(usize) -> Mesh<D>,
    formulation: Formulation,
    exact: Arc<dyn Manufactured<D>>,
    dirichlet: &[(&str, Vec<usize>)],
    traction: &[&str],
) -> Result<StokesRun, FlowError> {
    let mut errs = Vec::new();
    let mut dofs = Vec::new();
    let mut max_div: f64 = 0.0;
    for &n in levels {
        let (e, nd) = stokes_errors(mesh_of(n), formulation, exact.clone(), dirichlet, traction)?;
        max_div = max_div.max(e.max_cell_divergence);
        errs.push(e);
        dofs.push(nd);
    }
    let h: Vec<f64> = levels.iter().map(|&n| 1.0 / n as f64).collect();
    Ok(StokesRun { studies: three_studies(name, &h, &errs), max_cell_divergence: max_div, dofs })
}

/// Stokes on the unit square with P2+/P1disc.
pub fn stokes_plane(effort: Effort) -> Result<StokesRun, FlowError> {
    let levels: &[usize] = if effort == Effort::Quick { &[4, 8, 16] } else { &[4, 8, 16, 32] };
    run_levels(
        "stokes-plane",
        levels,
        |n| rectangle_triangles(0.0, 1.0, 0.0, 1.0, n, n, DiagonalPattern::Alternating),
        Formulation::Plane,
        Arc::new(PlaneStokes { eta: 1.0 }),
        &[("left", vec![0, 1]), ("bottom", vec![0, 1]), ("top", vec![0, 1])],
        &["right"],
    )
}

/// Axisymmetric Stokes on `(z, r)` in the unit square; `bottom` (r = 0) is the symmetry axis.
pub fn stokes_axisymmetric(effort: Effort) -> Result<StokesRun, FlowError> {
    let levels: &[usize] = if effort == Effort::Quick { &[4, 8, 16] } else { &[4, 8, 16, 32] };
    run_levels(
        "stokes-axisymmetric",
        levels,
        |n| rectangle_triangles(0.0, 1.0, 0.0, 1.0, n, n, DiagonalPattern::Alternating),
        Formulation::Axisymmetric,
        Arc::new(AxisymmetricStokes { eta: 1.0 }),
        &[("bottom", vec![1]), ("left", vec![0, 1]), ("top", vec![0, 1])],
        &["right"],
    )
}

/// Stokes on the unit cube with 15-node P2+ tetrahedra.
pub fn stokes_3d(effort: Effort) -> Result<StokesRun, FlowError> {
    let levels: &[usize] = if effort == Effort::Quick { &[2, 3, 4] } else { &[2, 4, 6, 8] };
    run_levels(
        "stokes-3d",
        levels,
        |n| box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, n, n, n),
        Formulation::ThreeD,
        Arc::new(Stokes3d { eta: 1.0 }),
        &STOKES_3D_VELOCITY.iter().map(|&f| (f, vec![0, 1, 2])).collect::<Vec<_>>(),
        &STOKES_3D_TRACTION,
    )
}

/// A failure of a verification study.
#[derive(Debug, thiserror::Error)]
pub enum VerifyError {
    #[error(transparent)]
    Flow(#[from] FlowError),
    #[error(transparent)]
    Time(#[from] crate::time::TimeError),
    #[error(transparent)]
    Solid(#[from] crate::discretize::solid::SolidError),
}

/// All studies of `fdfsi verify`: Stokes (plane, axisymmetric, 3D), time convergence (Euler,
/// BDF2) of a flow and of a solid, and the neo-Hookean solid (Rivlin bending, cylinder inflation
/// in plane strain and axisymmetric; see [`solid_exact`]).
pub fn run_all(effort: Effort, mut progress: impl FnMut(&str)) -> Result<(VerifyReport, Vec<StokesRun>), VerifyError> {
    let mut runs = Vec::new();
    progress("stokes-plane");
    runs.push(stokes_plane(effort)?);
    progress("stokes-axisymmetric");
    runs.push(stokes_axisymmetric(effort)?);
    progress("stokes-3d");
    runs.push(stokes_3d(effort)?);
    let mut studies: Vec<Study> = runs.iter().flat_map(|r| r.studies.clone()).collect();
    progress("kovasznay, kovasznay-supg");
    studies.extend(kovasznay(effort, Stabilization::None)?);
    studies.extend(kovasznay(effort, Stabilization::Supg)?);
    progress("time-euler, time-bdf2");
    studies.push(time_convergence(crate::time::TimeScheme::Euler)?);
    studies.push(time_convergence(crate::time::TimeScheme::Bdf2)?);
    progress("solid-dynamics-euler, solid-dynamics-bdf2");
    studies.push(solid_time_convergence(crate::time::TimeScheme::Euler)?);
    studies.push(solid_time_convergence(crate::time::TimeScheme::Bdf2)?);
    progress("solid: rivlin-bending, cylinder-inflation, homogeneous states");
    for run in solid_exact::solid_studies(effort)? {
        studies.extend(run.studies);
    }
    let checks = solid_exact::homogeneous_checks()?;
    Ok((VerifyReport { studies, checks }, runs))
}

/// Kovasznay flow (steady Navier-Stokes, Re = 40) on `[-0.5, 1] x [-0.5, 1.5]` with the exact
/// velocity on the whole boundary (pressure fixed to zero mean); EXACT-SOLUTIONS.md 2.4:
/// `u = 1 - e^{l x} cos(2 pi y)`, `v = l/(2 pi) e^{l x} sin(2 pi y)`, `p = (1 - e^{2 l x}) / 2`
/// (+ const), `l = Re/2 - sqrt(Re^2/4 + 4 pi^2)`. Expected rates 3 (velocity L2), 2 (H1, p),
/// with SUPG too (`kovasznay-supg`: the stabilisation is consistent).
pub fn kovasznay(effort: Effort, stabilization: Stabilization) -> Result<Vec<Study>, FlowError> {
    use std::f64::consts::PI;
    let re = 40.0;
    let l = re / 2.0 - (re * re / 4.0 + 4.0 * PI * PI).sqrt();
    let vel = move |x: &[f64; 2]| {
        let e = (l * x[0]).exp();
        [1.0 - e * (2.0 * PI * x[1]).cos(), l / (2.0 * PI) * e * (2.0 * PI * x[1]).sin()]
    };
    let grad = move |x: &[f64; 2]| {
        let e = (l * x[0]).exp();
        let (s, c) = ((2.0 * PI * x[1]).sin(), (2.0 * PI * x[1]).cos());
        [[-l * e * c, 2.0 * PI * e * s], [l * l / (2.0 * PI) * e * s, l * e * c]]
    };
    let levels: &[usize] = if effort == Effort::Quick { &[4, 8, 16] } else { &[4, 8, 16, 32] };
    let mut errs = Vec::new();
    for &n in levels {
        let mesh = rectangle_triangles(-0.5, 1.0, -0.5, 1.5, 3 * n / 2, 2 * n, DiagonalPattern::Alternating);
        let disc = FlowDiscretization::build(mesh, Formulation::Plane)?;
        let bc = |name: &str| DirichletBc { boundary: name.into(), components: vec![0, 1], value: Arc::new(move |x: &[f64; 2], _| vel(x)) };
        let problem = FlowProblem {
            formulation: Formulation::Plane,
            params: FluidParams {
                viscosity: 1.0 / re,
                density: 1.0,
                inv_dt: 0.0,
                convection: true,
                convective_form: Default::default(),
                viscous_form: Default::default(),
                stabilization,
            },
            body_force: None,
            dirichlet: ["left", "right", "bottom", "top"].iter().map(|b| bc(b)).collect(),
            traction: vec![],
            pin_pressure: true,
            windkessel: Vec::new(),
            backflow: Vec::new(),
            symmetry: Vec::new(),
        };
        let sol = solve_steady(&disc, &problem, &mut FaerLu::default(), &NewtonOptions::default())?;
        // The discrete pressure has zero mean; compare with the exact pressure shifted likewise.
        let mean = exact_mean_pressure(l);
        let p = move |x: &[f64; 2]| 0.5 * (1.0 - (2.0 * l * x[0]).exp()) - mean;
        errs.push(flow_errors(&disc, Formulation::Plane, &sol.x, &ExactFlow { velocity: &vel, gradient: &grad, pressure: &p }, 8)?);
    }
    let h: Vec<f64> = levels.iter().map(|&n| 1.0 / n as f64).collect();
    let name = match stabilization {
        Stabilization::None => "kovasznay",
        Stabilization::Supg => "kovasznay-supg",
    };
    Ok(three_studies(name, &h, &errs))
}

/// Mean of `(1 - e^{2 l x}) / 2` over `[-0.5, 1] x [-0.5, 1.5]`.
fn exact_mean_pressure(l: f64) -> f64 {
    let int_x = 1.5 - ((2.0 * l).exp() - (-l).exp()) / (2.0 * l);
    0.5 * int_x / 1.5
}

/// Time convergence of implicit Euler or BDF2 on a manufactured Navier-Stokes solution
/// (module doc): velocity L2 error at `T = 1` for `dt = 1/10 .. 1/80`.
pub fn time_convergence(scheme: crate::time::TimeScheme) -> Result<Study, crate::time::TimeError> {
    use crate::time::TimeScheme;
    let steps = [10usize, 20, 40, 80];
    let errors = steps.iter().map(|&n| time_error(scheme, 1.0 / n as f64, 1.0)).collect::<Result<Vec<_>, _>>()?;
    let h: Vec<f64> = steps.iter().map(|&n| 1.0 / n as f64).collect();
    let (name, rate) = match scheme {
        TimeScheme::Euler => ("time-euler", 1.0),
        TimeScheme::Bdf2 => ("time-bdf2", 2.0),
    };
    Ok(Study::new(name, "velocity_l2", rate, &h, errors))
}

/// The velocity L2 error at `t_end` of the manufactured Navier-Stokes solution of
/// [`time_convergence`] (module doc) with steps of `dt` (the last one shorter when `t_end` is
/// not a whole number of them).
pub fn time_error(scheme: crate::time::TimeScheme, dt: f64, t_end: f64) -> Result<f64, crate::time::TimeError> {
    use crate::time::{solve_unsteady, TimeOptions};
    let g = |t: f64| (2.0 * t).sin();
    let dg = |t: f64| 2.0 * (2.0 * t).cos();
    let exact = move |x: &[f64; 2], t: f64| [g(t) * x[1] * (1.0 - x[1]), 0.0];
    let mesh = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 3, 3, DiagonalPattern::Alternating);
    let disc = FlowDiscretization::build(mesh, Formulation::Plane)?;
    let bc = |name: &str| DirichletBc { boundary: name.into(), components: vec![0, 1], value: Arc::new(exact) };
    let problem = FlowProblem {
        formulation: Formulation::Plane,
        params: FluidParams {
            viscosity: 1.0,
            density: 1.0,
            inv_dt: 0.0,
            convection: true,
            convective_form: Default::default(),
            viscous_form: Default::default(),
            stabilization: Default::default(),
        },
        body_force: Some(Arc::new(move |x: &[f64; 2], t| [dg(t) * x[1] * (1.0 - x[1]) + 2.0 * g(t), 0.0])),
        dirichlet: ["left", "right", "bottom", "top"].iter().map(|b| bc(b)).collect(),
        traction: vec![],
        pin_pressure: true,
        windkessel: Vec::new(),
        backflow: Vec::new(),
        symmetry: Vec::new(),
    };
    let mut x = vec![0.0; disc.num_dofs()];
    let options = TimeOptions { dt, t_end, scheme, max_cuts: 0 };
    let mut lu = FaerLu::default();
    solve_unsteady(&disc, &problem, &mut x, &options, &mut lu, &NewtonOptions::default(), |_, _| Ok(()))?;
    let (u, gr, p) = (|x: &[f64; 2]| exact(x, t_end), |x: &[f64; 2]| [[0.0, g(t_end) * (1.0 - 2.0 * x[1])], [0.0, 0.0]], |_: &[f64; 2]| 0.0);
    Ok(flow_errors(&disc, Formulation::Plane, &x, &ExactFlow { velocity: &u, gradient: &gr, pressure: &p }, 6)?.velocity_l2)
}

/// Time convergence of a solid with inertia, implicit Euler or BDF2, on the affine motion of the
/// module doc: displacement L2 error at `T = 0.5` for `dt = T/10 .. T/80`.
pub fn solid_time_convergence(scheme: crate::time::TimeScheme) -> Result<Study, VerifyError> {
    use crate::discretize::solid::{solid_errors, ExactSolid, SolidDiscretization, SolidProblem};
    use crate::physics::solid::{SaintVenantKirchhoff, SolidMaterial};
    use crate::time::march::Stepper;
    use crate::time::solid::{DynamicState, DynamicStepper};
    use crate::time::TimeScheme;
    use std::f64::consts::PI;
    const A: [[f64; 2]; 2] = [[0.05, 0.02], [-0.03, 0.04]];
    let (mu, lambda, rho, t_end) = (1.0, 1.5, 1.0, 0.5);
    let s = |t: f64| 1.0 - (2.0 * PI * t).cos();
    let s2 = |t: f64| 4.0 * PI * PI * (2.0 * PI * t).cos();
    let affine = |c: f64, x: &[f64; 2]| -> [f64; 2] { std::array::from_fn(|i| c * (A[i][0] * x[0] + A[i][1] * x[1])) };
    // First Piola-Kirchhoff stress P = F S, S = lambda tr(E) I + 2 mu E (plane strain).
    let stress = move |t: f64| -> [[f64; 2]; 2] {
        let f: [[f64; 2]; 2] = std::array::from_fn(|i| std::array::from_fn(|j| if i == j { 1.0 } else { 0.0 } + s(t) * A[i][j]));
        let e: [[f64; 2]; 2] =
            std::array::from_fn(|i| std::array::from_fn(|j| 0.5 * ((0..2).map(|k| f[k][i] * f[k][j]).sum::<f64>() - if i == j { 1.0 } else { 0.0 })));
        let tr = e[0][0] + e[1][1];
        let ss: [[f64; 2]; 2] = std::array::from_fn(|i| std::array::from_fn(|j| 2.0 * mu * e[i][j] + if i == j { lambda * tr } else { 0.0 }));
        std::array::from_fn(|i| std::array::from_fn(|j| (0..2).map(|k| f[i][k] * ss[k][j]).sum()))
    };
    let material: Arc<dyn SolidMaterial> = Arc::new(SaintVenantKirchhoff { mu, lambda });
    let mut problem = SolidProblem::new(Formulation::Plane, material.clone())
        .with_displacement("left", &[0, 1], move |x, t| affine(s(t), x))
        .with_displacement("bottom", &[0, 1], move |x, t| affine(s(t), x))
        .with_traction("right", move |_, t| {
            let p = stress(t);
            [p[0][0], p[1][0]]
        })
        .with_traction("top", move |_, t| {
            let p = stress(t);
            [p[0][1], p[1][1]]
        });
    problem.bodies[0].density = rho;
    problem.bodies[0].body_force = Some(Arc::new(move |x: &[f64; 2], t| affine(rho * s2(t), x)));
    let mesh = fdfsi_fem::generate::rectangle_quads(0.0, 1.0, 0.0, 1.0, 2, 2, fdfsi_fem::mesh::GeometryOrder::Quadratic);
    let disc = SolidDiscretization::build(mesh, Formulation::Plane, material.as_ref())?;
    let steps = [10usize, 20, 40, 80];
    let mut errors = Vec::new();
    for &n in &steps {
        let mut lu = FaerLu::default();
        let newton = NewtonOptions { abs_tol: 1e-12, rel_tol: 1e-12, ..Default::default() };
        let mut stepper = DynamicStepper::new(&disc, &problem, &mut lu, newton, scheme, DynamicState::at_rest(disc.num_dofs()));
        let dt = t_end / n as f64;
        for k in 0..n {
            stepper.advance(k as f64 * dt, (k + 1) as f64 * dt, false)?;
        }
        let c = s(t_end);
        let (u, g) = (move |x: &[f64; 2]| affine(c, x), move |_: &[f64; 2]| std::array::from_fn(|i| std::array::from_fn(|j| c * A[i][j])));
        let e = solid_errors(&disc, &stepper.state.x, &ExactSolid { displacement: &u, gradient: &g, pressure: None }, 6)?;
        errors.push(e.displacement_l2);
    }
    let h: Vec<f64> = steps.iter().map(|&n| t_end / n as f64).collect();
    let (name, rate) = match scheme {
        TimeScheme::Euler => ("solid-dynamics-euler", 1.0),
        TimeScheme::Bdf2 => ("solid-dynamics-bdf2", 2.0),
    };
    Ok(Study::new(name, "displacement_l2", rate, &h, errors))
}
