//! Exact solutions of incompressible neo-Hookean elasticity (EXACT-SOLUTIONS.md section 1) and
//! the solid verification studies built on them.
//!
//! Pressures are given in the convention of the paper and of the kernel,
//! `sigma = G (B - I) - p I`; EXACT-SOLUTIONS.md writes `sigma = -p' I + G B`, so `p = p' - G`.
//!
//! | study | mesh | boundary conditions | expected rate (u L2) |
//! |---|---|---|---|
//! | `solid-bending` | block `[0,H] x [-L/2,L/2]`, Q2 quads | exact map on the end faces `X_2 = +-L/2`, curved faces free | 3 |
//! | `solid-cylinder-plane` | quarter annulus `A <= R <= B`, curved Q2 | exact inner displacement, symmetry rollers, outer face free | 3 |
//! | `solid-cylinder-axisymmetric` | `(z, r)` in `[0, h] x [A, B]` | exact inner `u_r`, rollers `u_z = 0` on both ends, outer free | 3 |
//!
//! Cook's membrane ([`cook_membrane`]) has no exact solution: it reports the tip displacement of
//! the mixed Q2/P1disc and of the displacement-only Q2 discretisation side by side.

use super::{Effort, Study};
use crate::discretize::solid::{
    pressure_at, solid_errors, solve_quasi_static, ExactSolid, Lagrangian, LoadStepping, SolidDiscretization, SolidError, SolidErrors, SolidProblem,
};
use crate::physics::fluid::Formulation;
use crate::physics::solid::{FibreReinforced, NeoHookeanCompressible, NeoHookeanMixed, SolidMaterial};
use crate::solve::linear::FaerLu;
use crate::solve::newton::NewtonOptions;
use fdfsi_fem::generate::rectangle_quads;
use fdfsi_fem::mesh::{GeometryOrder, Mesh};
use std::f64::consts::FRAC_PI_2;
use std::sync::Arc;

/// Plane-strain uniaxial stretch `lambda` along `x`: `x = lambda X`, `y = Y / lambda`,
/// `sigma_22 = 0`, `p = G (lambda^-2 - 1)`.
#[derive(Clone, Copy, Debug)]
pub struct UniaxialPlaneStrain {
    pub shear_modulus: f64,
    pub stretch: f64,
}

impl UniaxialPlaneStrain {
    pub fn displacement(&self, x: &[f64; 2]) -> [f64; 2] {
        [(self.stretch - 1.0) * x[0], (1.0 / self.stretch - 1.0) * x[1]]
    }
    /// Paper's pressure `p = p' - G` with `p' = G lambda^-2`.
    pub fn pressure(&self) -> f64 {
        self.shear_modulus * (self.stretch.powi(-2) - 1.0)
    }
    /// `sigma_11 = G (lambda^2 - lambda^-2)`.
    pub fn sigma_11(&self) -> f64 {
        self.shear_modulus * (self.stretch.powi(2) - self.stretch.powi(-2))
    }
}

/// 3D (and axisymmetric) uniaxial stretch `lambda` along the first axis: lateral stretches
/// `lambda^{-1/2}`, `p = G (1/lambda - 1)`.
#[derive(Clone, Copy, Debug)]
pub struct Uniaxial3d {
    pub shear_modulus: f64,
    pub stretch: f64,
}

impl Uniaxial3d {
    pub fn displacement<const D: usize>(&self, x: &[f64; D]) -> [f64; D] {
        let lat = self.stretch.powf(-0.5) - 1.0;
        std::array::from_fn(|d| if d == 0 { (self.stretch - 1.0) * x[0] } else { lat * x[d] })
    }
    pub fn pressure(&self) -> f64 {
        self.shear_modulus * (1.0 / self.stretch - 1.0)
    }
}

/// Uniaxial stretch `lambda` along fibres that lie along the stretch (`a_0 = e_1`): the paper's
/// incompressible matrix `G` with Holzapfel-Gasser-Ogden fibres `k1, k2`
/// ([`FibreReinforced`]), in plane strain (lateral stretch `l = 1/lambda`, `F_33 = 1`) or 3D
/// (`l = lambda^{-1/2}` in both lateral directions). The fibres add to `sigma_11` alone, so the
/// lateral stresses vanish with the matrix's pressure, `p = G (l^2 - 1)`, and
///
/// ```text
/// sigma_11 = G (lambda^2 - l^2) + 2 psi'(lambda^2) lambda^2,   psi'(I4) = k1 (I4 - 1) exp(k2 (I4 - 1)^2),
/// P_11     = sigma_11 / lambda                                 (the nominal traction on X_1 = const).
/// ```
#[derive(Clone, Copy, Debug)]
pub struct FibreUniaxial {
    pub shear_modulus: f64,
    pub k1: f64,
    pub k2: f64,
    pub stretch: f64,
    /// Plane strain (`true`) or 3D.
    pub plane_strain: bool,
}

impl FibreUniaxial {
    /// The lateral stretch `l`.
    pub fn lateral(&self) -> f64 {
        if self.plane_strain {
            1.0 / self.stretch
        } else {
            self.stretch.powf(-0.5)
        }
    }
    pub fn displacement<const D: usize>(&self, x: &[f64; D]) -> [f64; D] {
        let l = self.lateral();
        std::array::from_fn(|d| if d == 0 { (self.stretch - 1.0) * x[0] } else { (l - 1.0) * x[d] })
    }
    /// The paper's pressure `p = G (l^2 - 1)`.
    pub fn pressure(&self) -> f64 {
        self.shear_modulus * (self.lateral().powi(2) - 1.0)
    }
    /// `P_11`, the nominal traction that holds the stretch.
    pub fn nominal_traction(&self) -> f64 {
        let (lam, l) = (self.stretch, self.lateral());
        let e = lam * lam - 1.0;
        let psi1 = self.k1 * e * (self.k2 * e * e).exp();
        (self.shear_modulus * (lam * lam - l * l) + 2.0 * psi1 * lam * lam) / lam
    }
    /// The law: fibres along `e_1` on the incompressible matrix.
    pub fn material(&self) -> Arc<dyn SolidMaterial> {
        let matrix = Arc::new(NeoHookeanMixed::incompressible(self.shear_modulus));
        Arc::new(FibreReinforced { matrix, k1: self.k1, k2: self.k2, onset: 0.0, direction: Arc::new(|_| [1.0, 0.0, 0.0]) })
    }
}

/// Simple shear `x = X + gamma Y`, `y = Y`.
#[derive(Clone, Copy, Debug)]
pub struct SimpleShear {
    pub gamma: f64,
}

impl SimpleShear {
    pub fn displacement(&self, x: &[f64; 2]) -> [f64; 2] {
        [self.gamma * x[1], 0.0]
    }
}

/// Rivlin's bending of the block `X_1 in [0, H]`, `X_2 in [-L/2, L/2]` into a sector of angle
/// `Theta` (plane strain): `r^2 = 2 alpha X_1 + a^2`, `theta = X_2 / alpha`, `alpha = L / Theta`,
/// traction-free curved faces.
#[derive(Clone, Copy, Debug)]
pub struct RivlinBending {
    pub mu: f64,
    pub h: f64,
    pub l: f64,
    pub theta: f64,
}

impl RivlinBending {
    /// The worked example: `mu = 1, H = 1, L = 4, Theta = pi/2`.
    pub fn worked_example() -> Self {
        RivlinBending { mu: 1.0, h: 1.0, l: 4.0, theta: FRAC_PI_2 }
    }
    pub fn alpha(&self) -> f64 {
        self.l / self.theta
    }
    /// Inner radius `a = sqrt(alpha (sqrt(H^2 + alpha^2) - H))`.
    pub fn a(&self) -> f64 {
        let al = self.alpha();
        (al * ((self.h * self.h + al * al).sqrt() - self.h)).sqrt()
    }
    /// Outer radius.
    pub fn b(&self) -> f64 {
        let al = self.alpha();
        (al * ((self.h * self.h + al * al).sqrt() + self.h)).sqrt()
    }
    /// Bending moment per unit depth.
    pub fn moment(&self) -> f64 {
        let (a, b) = (self.a(), self.b());
        self.mu * ((b.powi(4) - a.powi(4)) / (8.0 * a * b) - 0.5 * a * b * (b / a).ln())
    }
    /// `sigma_rr(r)`.
    pub fn sigma_rr(&self, r: f64) -> f64 {
        let (al, a) = (self.alpha(), self.a());
        self.mu * ((r * r - a * a) / (2.0 * al * al) + 0.5 * al * al * (1.0 / (r * r) - 1.0 / (a * a)))
    }
    /// `sigma_thetatheta(r)`.
    pub fn sigma_tt(&self, r: f64) -> f64 {
        let al = self.alpha();
        self.sigma_rr(r) + self.mu * (r * r / (al * al) - al * al / (r * r))
    }
    /// Radius of material point `x`.
    pub fn radius(&self, x: &[f64; 2]) -> f64 {
        let a = self.a();
        (2.0 * self.alpha() * x[0] + a * a).sqrt()
    }
    /// Deformed position.
    pub fn position(&self, x: &[f64; 2]) -> [f64; 2] {
        let r = self.radius(x);
        let th = x[1] / self.alpha();
        [r * th.cos(), r * th.sin()]
    }
    pub fn displacement(&self, x: &[f64; 2]) -> [f64; 2] {
        let p = self.position(x);
        [p[0] - x[0], p[1] - x[1]]
    }
    /// `Grad u = F - I`.
    pub fn gradient(&self, x: &[f64; 2]) -> [[f64; 2]; 2] {
        let (al, r) = (self.alpha(), self.radius(x));
        let th = x[1] / al;
        let (c, s) = (th.cos(), th.sin());
        [[al * c / r - 1.0, -r * s / al], [al * s / r, r * c / al - 1.0]]
    }
    /// Paper's pressure `p = (mu alpha^2/r^2 - sigma_rr) - mu`.
    pub fn pressure(&self, x: &[f64; 2]) -> f64 {
        let (al, r) = (self.alpha(), self.radius(x));
        self.mu * al * al / (r * r) - self.sigma_rr(r) - self.mu
    }
    /// A load path to the exact map: bending by the fraction `load` of the angle, shifted by the
    /// rigid translation `-(a(load) - load a, 0)` so that the path starts at the identity and
    /// ends at [`Self::displacement`]. Every intermediate state is an exact solution.
    pub fn displacement_at_load(&self, x: &[f64; 2], load: f64) -> [f64; 2] {
        if load.abs() < 1e-12 {
            return [0.0, 0.0];
        }
        let part = RivlinBending { theta: self.theta * load, ..*self };
        let u = part.displacement(x);
        [u[0] - (part.a() - load * self.a()), u[1]]
    }
}

/// Inflation of a thick-walled cylinder (plane strain, or axisymmetric with no axial
/// displacement): `r^2 - R^2 = a^2 - A^2`, traction-free outer surface.
#[derive(Clone, Copy, Debug)]
pub struct CylinderInflation {
    pub mu: f64,
    /// Reference inner radius `A`.
    pub inner: f64,
    /// Reference outer radius `B`.
    pub outer: f64,
    /// Deformed inner radius `a`.
    pub a: f64,
}

impl CylinderInflation {
    /// The worked example `A = 1, B = 1.5, a = 1.3` (`P_i = 0.21541965495917 mu`).
    pub fn worked_example() -> Self {
        CylinderInflation { mu: 1.0, inner: 1.0, outer: 1.5, a: 1.3 }
    }
    fn c(&self) -> f64 {
        self.a * self.a - self.inner * self.inner
    }
    /// Deformed outer radius.
    pub fn b(&self) -> f64 {
        (self.outer * self.outer + self.c()).sqrt()
    }
    /// Deformed radius of reference radius `r0`.
    pub fn radius(&self, r0: f64) -> f64 {
        (r0 * r0 + self.c()).sqrt()
    }
    /// `F(rho) = -ln l + 1/(2 l^2) - 1/2` with `l = rho / R(rho)`: `sigma_rr(r) = -P_i + mu (F(r) - F(a))`.
    fn f_int(&self, r: f64) -> f64 {
        let l = r / (r * r - self.c()).sqrt();
        -l.ln() + 0.5 / (l * l) - 0.5
    }
    /// Internal pressure `P_i = mu [ln(l_a/l_b) + 1/(2 l_b^2) - 1/(2 l_a^2)]`.
    pub fn internal_pressure(&self) -> f64 {
        self.mu * (self.f_int(self.b()) - self.f_int(self.a))
    }
    /// `sigma_rr` at deformed radius `r`.
    pub fn sigma_rr(&self, r: f64) -> f64 {
        -self.internal_pressure() + self.mu * (self.f_int(r) - self.f_int(self.a))
    }
    /// Paper's pressure at reference radius `r0`: `p = mu (lambda_r^2 - 1) - sigma_rr`.
    pub fn pressure_at_radius(&self, r0: f64) -> f64 {
        let r = self.radius(r0);
        self.mu * ((r0 / r).powi(2) - 1.0) - self.sigma_rr(r)
    }
    /// Plane strain: displacement of material point `x` (centre at the origin).
    pub fn displacement_plane(&self, x: &[f64; 2]) -> [f64; 2] {
        let r0 = (x[0] * x[0] + x[1] * x[1]).sqrt();
        let s = self.radius(r0) / r0 - 1.0;
        [s * x[0], s * x[1]]
    }
    /// Plane strain: `Grad u = (r/R - 1) I - c/(r R^3) X X^T`.
    pub fn gradient_plane(&self, x: &[f64; 2]) -> [[f64; 2]; 2] {
        let r0 = (x[0] * x[0] + x[1] * x[1]).sqrt();
        let r = self.radius(r0);
        let k = self.c() / (r * r0.powi(3));
        std::array::from_fn(|i| std::array::from_fn(|j| if i == j { r / r0 - 1.0 } else { 0.0 } - k * x[i] * x[j]))
    }
    /// Axisymmetric `(z, r)`: `u = (0, r(R) - R)`.
    pub fn displacement_axi(&self, x: &[f64; 2]) -> [f64; 2] {
        [0.0, self.radius(x[1]) - x[1]]
    }
    pub fn gradient_axi(&self, x: &[f64; 2]) -> [[f64; 2]; 2] {
        [[0.0, 0.0], [0.0, x[1] / self.radius(x[1]) - 1.0]]
    }
    /// The same cylinder with the inner radius moved the fraction `load` of the way to `a`.
    pub fn at_load(&self, load: f64) -> Self {
        CylinderInflation { a: self.inner + load * (self.a - self.inner), ..*self }
    }
}

/// Quarter annulus `A <= R <= B`, `0 <= phi <= pi/2`, with curved Q2 cells: the image of a
/// `(R, phi)` rectangle mesh under the polar map (every Q2 node mapped exactly). Boundaries:
/// `"inner"`, `"outer"`, `"symmetry_y"` (`phi = 0`, the x axis: `u_y = 0`), `"symmetry_x"`
/// (`phi = pi/2`: `u_x = 0`).
pub fn quarter_annulus(inner: f64, outer: f64, n_radial: usize, n_angular: usize) -> Mesh<2> {
    let mut m = rectangle_quads(inner, outer, 0.0, FRAC_PI_2, n_radial, n_angular, GeometryOrder::Quadratic);
    for p in m.points.iter_mut() {
        let (r, phi) = (p[0], p[1]);
        *p = [r * phi.cos(), r * phi.sin()];
    }
    m.boundary_names = vec![("inner".into(), 1), ("outer".into(), 2), ("symmetry_y".into(), 3), ("symmetry_x".into(), 4)];
    m
}

/// Cook's membrane: the bilinear image of the unit square onto the quadrilateral
/// `(0,0), (48,44), (48,60), (0,44)` with `n x n` Q2 cells. Boundaries `"left"` (clamped),
/// `"right"` (loaded), `"bottom"`, `"top"`.
pub fn cook_mesh(n: usize) -> Mesh<2> {
    let mut m = rectangle_quads(0.0, 1.0, 0.0, 1.0, n, n, GeometryOrder::Quadratic);
    for p in m.points.iter_mut() {
        let (s, t) = (p[0], p[1]);
        *p = [48.0 * s, 44.0 * s + 44.0 * t - 28.0 * s * t];
    }
    m
}

/// Newton options of the studies: tight, as the exact solutions are smooth.
pub fn study_newton() -> NewtonOptions {
    NewtonOptions { max_iterations: 25, abs_tol: 1e-11, rel_tol: 1e-11, ..Default::default() }
}

/// A solid convergence run: the studies and the raw numbers.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SolidRun {
    pub studies: Vec<Study>,
    pub errors: Vec<SolidErrors>,
    pub dofs: Vec<usize>,
    /// Newton residual norms of every converged increment of the finest mesh.
    pub residuals_finest: Vec<Vec<f64>>,
}

fn run_studies(name: &str, h: &[f64], errs: Vec<SolidErrors>, dofs: Vec<usize>, residuals_finest: Vec<Vec<f64>>) -> SolidRun {
    let studies = vec![
        Study::new(name, "displacement_l2", 3.0, h, errs.iter().map(|e| e.displacement_l2).collect()),
        Study::new(name, "displacement_h1", 2.0, h, errs.iter().map(|e| e.displacement_h1).collect()),
        Study::new(name, "pressure_l2", 2.0, h, errs.iter().map(|e| e.pressure_l2).collect()),
    ];
    SolidRun { studies, errors: errs, dofs, residuals_finest }
}

/// Rivlin bending (worked example) on `n x 4n` Q2/P1disc meshes, the exact map prescribed on the
/// end faces (bending angle ramped in `steps` increments).
pub fn rivlin_bending(effort: Effort) -> Result<SolidRun, SolidError> {
    let ex = RivlinBending::worked_example();
    let levels: &[usize] = if effort == Effort::Quick { &[1, 2, 4] } else { &[1, 2, 4, 8] };
    let material: Arc<dyn SolidMaterial> = Arc::new(NeoHookeanMixed::incompressible(ex.mu));
    let (mut errs, mut dofs, mut res) = (Vec::new(), Vec::new(), Vec::new());
    for &n in levels {
        let mesh = rectangle_quads(0.0, ex.h, -ex.l / 2.0, ex.l / 2.0, n, 4 * n, GeometryOrder::Quadratic);
        let disc = SolidDiscretization::build(mesh, Formulation::Plane, material.as_ref())?;
        let bc = move |x: &[f64; 2], load: f64| ex.displacement_at_load(x, load);
        let problem =
            SolidProblem::new(Formulation::Plane, material.clone()).with_displacement("bottom", &[0, 1], bc).with_displacement("top", &[0, 1], bc);
        let stepping = LoadStepping::uniform(Lagrangian::Total, 4);
        let sol = solve_quasi_static(&disc, &problem, &stepping, &mut FaerLu::default(), &study_newton())?;
        let (u, g, p) = (|x: &[f64; 2]| ex.displacement(x), |x: &[f64; 2]| ex.gradient(x), |x: &[f64; 2]| ex.pressure(x));
        errs.push(solid_errors(&disc, &sol.x, &ExactSolid { displacement: &u, gradient: &g, pressure: Some(&p) }, 9)?);
        dofs.push(disc.num_dofs());
        res = sol.residual_history();
    }
    let h: Vec<f64> = levels.iter().map(|&n| 1.0 / n as f64).collect();
    Ok(run_studies("solid-bending", &h, errs, dofs, res))
}

/// Thick-walled cylinder inflation (worked example), plane strain on the quarter annulus or
/// axisymmetric on `(z, r) in [0, 0.5] x [A, B]`; the exact inner displacement is prescribed
/// (ramped in 2 increments).
pub fn cylinder_inflation(formulation: Formulation, effort: Effort) -> Result<SolidRun, SolidError> {
    let ex = CylinderInflation::worked_example();
    let levels: &[usize] = if effort == Effort::Quick { &[1, 2, 4] } else { &[1, 2, 4, 8] };
    let material: Arc<dyn SolidMaterial> = Arc::new(NeoHookeanMixed::incompressible(ex.mu));
    let (mut errs, mut dofs, mut res) = (Vec::new(), Vec::new(), Vec::new());
    let axi = formulation == Formulation::Axisymmetric;
    for &n in levels {
        let (mesh, problem) = if axi {
            let mesh = rectangle_quads(0.0, 0.5, ex.inner, ex.outer, n, 2 * n, GeometryOrder::Quadratic);
            let problem = SolidProblem::new(formulation, material.clone())
                .with_displacement("bottom", &[0, 1], move |x: &[f64; 2], l| ex.at_load(l).displacement_axi(x))
                .with_displacement("left", &[0], |_: &[f64; 2], _| [0.0; 2])
                .with_displacement("right", &[0], |_: &[f64; 2], _| [0.0; 2]);
            (mesh, problem)
        } else {
            let mesh = quarter_annulus(ex.inner, ex.outer, 2 * n, 3 * n);
            let problem = SolidProblem::new(formulation, material.clone())
                .with_displacement("inner", &[0, 1], move |x: &[f64; 2], l| ex.at_load(l).displacement_plane(x))
                .with_displacement("symmetry_y", &[1], |_: &[f64; 2], _| [0.0; 2])
                .with_displacement("symmetry_x", &[0], |_: &[f64; 2], _| [0.0; 2]);
            (mesh, problem)
        };
        let disc = SolidDiscretization::build(mesh, formulation, material.as_ref())?;
        let sol = solve_quasi_static(&disc, &problem, &LoadStepping::uniform(Lagrangian::Total, 2), &mut FaerLu::default(), &study_newton())?;
        let e = if axi {
            let (u, g) = (|x: &[f64; 2]| ex.displacement_axi(x), |x: &[f64; 2]| ex.gradient_axi(x));
            let p = |x: &[f64; 2]| ex.pressure_at_radius(x[1]);
            solid_errors(&disc, &sol.x, &ExactSolid { displacement: &u, gradient: &g, pressure: Some(&p) }, 9)?
        } else {
            let (u, g) = (|x: &[f64; 2]| ex.displacement_plane(x), |x: &[f64; 2]| ex.gradient_plane(x));
            let p = |x: &[f64; 2]| ex.pressure_at_radius((x[0] * x[0] + x[1] * x[1]).sqrt());
            solid_errors(&disc, &sol.x, &ExactSolid { displacement: &u, gradient: &g, pressure: Some(&p) }, 9)?
        };
        errs.push(e);
        dofs.push(disc.num_dofs());
        res = sol.residual_history();
    }
    let h: Vec<f64> = levels.iter().map(|&n| 1.0 / n as f64).collect();
    let name = if axi { "solid-cylinder-axisymmetric" } else { "solid-cylinder-plane" };
    Ok(run_studies(name, &h, errs, dofs, res))
}

/// Cook's membrane, one discretisation on one mesh: vertical tip displacement at (48, 60).
#[derive(Clone, Debug, serde::Serialize)]
pub struct CookResult {
    pub elements_per_side: usize,
    pub mixed_tip_uy: f64,
    pub displacement_only_tip_uy: f64,
}

/// Cook's membrane with the nearly incompressible neo-Hookean solid (G = 80.1938,
/// K = 40.0942e4, shear traction 6.25 per unit length on the right edge, left edge clamped,
/// plane strain): Q2/P1disc mixed ([`NeoHookeanMixed`]) beside displacement-only Q2
/// ([`NeoHookeanCompressible`] with the same G and K), on `n x n` meshes.
pub fn cook_membrane(levels: &[usize]) -> Result<Vec<CookResult>, SolidError> {
    let (g, k) = (80.1938, 40.0942e4);
    let mats: [Arc<dyn SolidMaterial>; 2] =
        [Arc::new(NeoHookeanMixed { shear_modulus: g, bulk_modulus: k }), Arc::new(NeoHookeanCompressible::from_shear_bulk(g, k))];
    let mut out = Vec::new();
    for &n in levels {
        let mut tips = [0.0; 2];
        for (m, mat) in mats.iter().enumerate() {
            let disc = SolidDiscretization::build(cook_mesh(n), Formulation::Plane, mat.as_ref())?;
            let problem = SolidProblem::new(Formulation::Plane, mat.clone())
                .with_displacement("left", &[0, 1], |_: &[f64; 2], _| [0.0; 2])
                .with_traction("right", |_: &[f64; 2], l| [0.0, 6.25 * l]);
            let stepping = LoadStepping { initial_increment: 0.5, max_increment: 0.5, min_increment: 1e-3, ..Default::default() };
            let sol = solve_quasi_static(
                &disc,
                &problem,
                &stepping,
                &mut FaerLu::default(),
                &NewtonOptions { max_iterations: 30, abs_tol: 1e-7, rel_tol: 1e-10, ..Default::default() },
            )?;
            tips[m] = disc.displacement(&sol.x, disc.node_near(&[48.0, 60.0]))[1];
        }
        out.push(CookResult { elements_per_side: n, mixed_tip_uy: tips[0], displacement_only_tip_uy: tips[1] });
    }
    Ok(out)
}

/// The solid studies of `fdfsi verify`.
pub fn solid_studies(effort: Effort) -> Result<Vec<SolidRun>, SolidError> {
    Ok(vec![rivlin_bending(effort)?, cylinder_inflation(Formulation::Plane, effort)?, cylinder_inflation(Formulation::Axisymmetric, effort)?])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The worked numbers of EXACT-SOLUTIONS.md section 1.
    #[test]
    fn worked_numbers_are_reproduced() {
        let b = RivlinBending::worked_example();
        assert!((b.alpha() - 2.5464790894703255).abs() < 1e-14);
        assert!((b.a() - 2.102416953827392).abs() < 1e-13);
        assert!((b.b() - 3.0843338383971184).abs() < 1e-13);
        assert!((b.moment() - 0.12529901945076682).abs() < 1e-12);
        assert!((b.sigma_tt(b.a()) + std::f64::consts::FRAC_PI_4).abs() < 1e-7);
        assert!((b.sigma_tt(b.b()) - std::f64::consts::FRAC_PI_4).abs() < 1e-7);
        assert!(b.sigma_rr(b.b()).abs() < 1e-13);
        // p' = p + mu at the faces: 1.4670419 and 0.6816438.
        assert!((b.pressure(&[0.0, 0.0]) + 1.0 - 1.4670419).abs() < 1e-7);
        assert!((b.pressure(&[1.0, 0.0]) + 1.0 - 0.6816438).abs() < 1e-7);
        assert!((b.sigma_rr(0.5 * (b.a() + b.b())) + 0.0736768).abs() < 1e-7);
        let c = CylinderInflation::worked_example();
        // b^2 = B^2 + a^2 - A^2 = 2.94: b = 1.7146428 (EXACT-SOLUTIONS.md prints 1.7058722, a
        // typo: P_i = 0.21541965495917 holds with b = sqrt(2.94)).
        assert!((c.b() - 2.94f64.sqrt()).abs() < 1e-15);
        assert!((c.internal_pressure() - 0.21541965495917).abs() < 1e-13);
        assert!((c.sigma_rr(c.a) + c.internal_pressure()).abs() < 1e-15);
        assert!(c.sigma_rr(c.b()).abs() < 1e-14);
        let u = UniaxialPlaneStrain { shear_modulus: 1.0, stretch: 1.5 };
        assert!((u.sigma_11() - 1.8055556).abs() < 1e-7);
        assert!((u.pressure() + 1.0 - 1.0 / 2.25).abs() < 1e-15);
    }

    /// The gradients are the derivatives of the displacements.
    #[test]
    fn exact_gradients_match_finite_differences() {
        let b = RivlinBending::worked_example();
        let c = CylinderInflation::worked_example();
        let h = 1e-6;
        let pts = [[0.3, 0.7], [0.8, -1.2], [1.1, 0.4]];
        for x in pts {
            type Displacement<'a> = &'a dyn Fn(&[f64; 2]) -> [f64; 2];
            let cases: [(Displacement, [[f64; 2]; 2]); 3] = [
                (&|p| b.displacement(p), b.gradient(&x)),
                (&|p| c.displacement_plane(p), c.gradient_plane(&[x[0] + 0.9, x[1].abs()])),
                (&|p| c.displacement_axi(p), c.gradient_axi(&[x[0], x[1].abs() + 1.0])),
            ];
            let pts_eval = [x, [x[0] + 0.9, x[1].abs()], [x[0], x[1].abs() + 1.0]];
            for (k, (u, g)) in cases.iter().enumerate() {
                let p = pts_eval[k];
                for j in 0..2 {
                    let (mut pp, mut pm) = (p, p);
                    pp[j] += h;
                    pm[j] -= h;
                    let (up, um) = (u(&pp), u(&pm));
                    for i in 0..2 {
                        let fd = (up[i] - um[i]) / (2.0 * h);
                        assert!((fd - g[i][j]).abs() < 1e-8, "case {k}: du_{i}/dX_{j}");
                    }
                }
            }
        }
    }
}

/// A homogeneous state that Q2/P1disc must reproduce to round-off.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ExactnessCheck {
    pub name: String,
    /// Largest nodal displacement error.
    pub displacement_error: f64,
    /// Largest pressure error over the quadrature points.
    pub pressure_error: f64,
}

/// Largest nodal displacement error and pressure error (all cells, all quadrature points).
fn homogeneous_errors<const D: usize>(disc: &SolidDiscretization<D>, x: &[f64], u: impl Fn(&[f64; D]) -> [f64; D], p: f64) -> (f64, f64) {
    let mut eu: f64 = 0.0;
    for (node, x0) in disc.nodes_x0.iter().enumerate() {
        let ue = u(x0);
        let uh = disc.displacement(x, node);
        for d in 0..D {
            eu = eu.max((uh[d] - ue[d]).abs());
        }
    }
    let mut ep: f64 = 0.0;
    let nq = disc.points_per_cell();
    for c in 0..disc.mesh.num_cells() {
        for q in 0..nq {
            ep = ep.max((pressure_at(disc, x, c, &disc.qp_x0[c * nq + q]) - p).abs());
        }
    }
    (eu, ep)
}

/// The homogeneous exact states of EXACT-SOLUTIONS.md 1.1-1.2 with the paper's incompressible
/// law: uniaxial stretch 1.5 in plane strain (G = 2, Q1 geometry), axisymmetric and 3D (27-node
/// hexahedra), and simple shear gamma = 0.5 with the displacement on the whole boundary and the
/// pressure pinned (it must come out uniform); then the fibre-reinforced law
/// ([`FibreUniaxial`]): stretch 1.3 along the fibres under the closed-form traction (plane
/// strain and 3D), and the plane-strain stretch 1.5 across them (the fibres shortened, idle).
pub fn homogeneous_checks() -> Result<Vec<ExactnessCheck>, SolidError> {
    use fdfsi_fem::generate::box_hexahedra;
    let solve = |disc: &SolidDiscretization<2>, problem: &SolidProblem<2>, steps: usize| {
        solve_quasi_static(disc, problem, &LoadStepping::uniform(Lagrangian::Total, steps), &mut FaerLu::default(), &study_newton())
    };
    let mut out = Vec::new();
    let mut push = |name: &str, (eu, ep): (f64, f64)| {
        out.push(ExactnessCheck { name: name.into(), displacement_error: eu, pressure_error: ep });
    };
    // Plane strain uniaxial: the unit square on rollers, its right side moved by 0.5.
    let g = 2.0;
    let ex = UniaxialPlaneStrain { shear_modulus: g, stretch: 1.5 };
    let uniaxial_plane = |mat: Arc<dyn SolidMaterial>| -> Result<(f64, f64), SolidError> {
        let disc = SolidDiscretization::build(rectangle_quads(0.0, 1.0, 0.0, 1.0, 3, 2, GeometryOrder::Linear), Formulation::Plane, mat.as_ref())?;
        let problem = SolidProblem::new(Formulation::Plane, mat)
            .with_displacement("left", &[0], |_: &[f64; 2], _| [0.0; 2])
            .with_displacement("bottom", &[1], |_: &[f64; 2], _| [0.0; 2])
            .with_displacement("right", &[0], |_: &[f64; 2], l| [0.5 * l, 0.0]);
        let sol = solve(&disc, &problem, 2)?;
        Ok(homogeneous_errors(&disc, &sol.x, |x| ex.displacement(x), ex.pressure()))
    };
    push("uniaxial-plane-strain", uniaxial_plane(Arc::new(NeoHookeanMixed::incompressible(g)))?);
    // Axisymmetric uniaxial: stretch along the axis z = x[0]; the axis r = 0 is "bottom".
    let ex3 = Uniaxial3d { shear_modulus: 1.0, stretch: 1.5 };
    let mat: Arc<dyn SolidMaterial> = Arc::new(NeoHookeanMixed::incompressible(1.0));
    let disc =
        SolidDiscretization::build(rectangle_quads(0.0, 1.0, 0.0, 1.0, 2, 2, GeometryOrder::Quadratic), Formulation::Axisymmetric, mat.as_ref())?;
    let problem = SolidProblem::new(Formulation::Axisymmetric, mat.clone())
        .with_displacement("left", &[0], |_: &[f64; 2], _| [0.0; 2])
        .with_displacement("bottom", &[1], |_: &[f64; 2], _| [0.0; 2])
        .with_displacement("right", &[0], |_: &[f64; 2], l| [0.5 * l, 0.0]);
    let sol = solve(&disc, &problem, 2)?;
    push("uniaxial-axisymmetric", homogeneous_errors(&disc, &sol.x, |x| ex3.displacement(x), ex3.pressure()));
    // 3D uniaxial on 27-node hexahedra.
    let disc = SolidDiscretization::build(
        box_hexahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 2, 1, 1, GeometryOrder::Quadratic),
        Formulation::ThreeD,
        mat.as_ref(),
    )?;
    let problem = SolidProblem::new(Formulation::ThreeD, mat.clone())
        .with_displacement("xmin", &[0], |_: &[f64; 3], _| [0.0; 3])
        .with_displacement("ymin", &[1], |_: &[f64; 3], _| [0.0; 3])
        .with_displacement("zmin", &[2], |_: &[f64; 3], _| [0.0; 3])
        .with_displacement("xmax", &[0], |_: &[f64; 3], l| [0.5 * l, 0.0, 0.0]);
    let sol = solve_quasi_static(&disc, &problem, &LoadStepping::uniform(Lagrangian::Total, 2), &mut FaerLu::default(), &study_newton())?;
    push("uniaxial-3d", homogeneous_errors(&disc, &sol.x, |x| ex3.displacement(x), ex3.pressure()));
    // Simple shear, fully Dirichlet, pressure pinned to 0.3.
    let sh = SimpleShear { gamma: 0.5 };
    let disc = SolidDiscretization::build(rectangle_quads(0.0, 1.0, 0.0, 1.0, 3, 3, GeometryOrder::Quadratic), Formulation::Plane, mat.as_ref())?;
    let mut problem = SolidProblem::new(Formulation::Plane, mat);
    for b in ["left", "right", "bottom", "top"] {
        problem = problem.with_displacement(b, &[0, 1], move |x: &[f64; 2], l| [l * sh.gamma * x[1], 0.0]);
    }
    problem.pin_pressure = Some(0.3);
    let sol = solve(&disc, &problem, 1)?;
    push("simple-shear", homogeneous_errors(&disc, &sol.x, |x| sh.displacement(x), 0.3));
    // Fibres along the stretch, loaded by the closed-form nominal traction (the stretch must come
    // out), plane strain and 3D: the fibres' exponential more than doubles P_11 at stretch 1.3.
    let fib = FibreUniaxial { shear_modulus: 2.0, k1: 3.0, k2: 2.0, stretch: 1.3, plane_strain: true };
    let traction = fib.nominal_traction();
    let disc =
        SolidDiscretization::build(rectangle_quads(0.0, 1.0, 0.0, 1.0, 3, 2, GeometryOrder::Linear), Formulation::Plane, fib.material().as_ref())?;
    let problem = SolidProblem::new(Formulation::Plane, fib.material())
        .with_displacement("left", &[0], |_: &[f64; 2], _| [0.0; 2])
        .with_displacement("bottom", &[1], |_: &[f64; 2], _| [0.0; 2])
        .with_traction("right", move |_: &[f64; 2], l| [l * traction, 0.0]);
    let sol = solve(&disc, &problem, 4)?;
    push("fibre-uniaxial-plane-strain", homogeneous_errors(&disc, &sol.x, |x| fib.displacement(x), fib.pressure()));
    let fib = FibreUniaxial { plane_strain: false, ..fib };
    let traction = fib.nominal_traction();
    let disc = SolidDiscretization::build(
        box_hexahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 2, 1, 1, GeometryOrder::Quadratic),
        Formulation::ThreeD,
        fib.material().as_ref(),
    )?;
    let problem = SolidProblem::new(Formulation::ThreeD, fib.material())
        .with_displacement("xmin", &[0], |_: &[f64; 3], _| [0.0; 3])
        .with_displacement("ymin", &[1], |_: &[f64; 3], _| [0.0; 3])
        .with_displacement("zmin", &[2], |_: &[f64; 3], _| [0.0; 3])
        .with_traction("xmax", move |_: &[f64; 3], l| [l * traction, 0.0, 0.0]);
    let sol = solve_quasi_static(&disc, &problem, &LoadStepping::uniform(Lagrangian::Total, 4), &mut FaerLu::default(), &study_newton())?;
    push("fibre-uniaxial-3d", homogeneous_errors(&disc, &sol.x, |x| fib.displacement(x), fib.pressure()));
    // Fibres across the stretch are shortened (I4 = lambda^-2 < 1) and bear nothing: the
    // neo-Hookean state of the first check.
    let matrix = Arc::new(NeoHookeanMixed::incompressible(ex.shear_modulus));
    let across = FibreReinforced { matrix, k1: fib.k1, k2: fib.k2, onset: 0.0, direction: Arc::new(|_| [0.0, 1.0, 0.0]) };
    push("fibre-across-plane-strain", uniaxial_plane(Arc::new(across))?);
    Ok(out)
}
