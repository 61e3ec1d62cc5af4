//! From a case to the objects of the numerical layers: meshes, flow and solid problems, the FSI
//! model and the probes. `fdfsi check`, `fdfsi run` and `fdfsi adapt` build them here alike.

use crate::adapt::{AdaptedFluid, CoveredFluid};
use crate::case::{BoundaryType, Case, CaseError, Expr, FlowModel, MeshSpec, TimeFn};
use crate::discretize::flow::{BackflowBc, DirichletBc, FlowError, FlowProblem, TractionBc, VectorFn, WindkesselBc};
use crate::discretize::fsi::FsiError;
use crate::discretize::solid::SolidError;
use crate::discretize::symmetry::SymmetryBc;
use crate::physics::fluid::FluidParams;
use fdfsi_fem::adapt::{AdaptError, AdaptOptions, AdaptStats, Background, Surface};
use fdfsi_fem::generate;
use fdfsi_fem::gmsh::{read_msh, AnyMesh, GmshError};
use fdfsi_fem::mesh::{Mesh, Topology};
use std::path::Path;
use std::sync::Arc;
use thiserror::Error;

mod fsi;
mod solid;

pub use fsi::fsi_model;
pub use solid::{displacement_probes, material, merge_surface, placed_solid_mesh, solid_mesh, solid_problem, SolidMesh};

/// A case that cannot be built: what is wrong, and where.
#[derive(Debug, Error)]
pub enum SetupError {
    #[error(transparent)]
    Case(#[from] CaseError),
    #[error(transparent)]
    Gmsh(#[from] GmshError),
    #[error("{file}: the mesh is {found}D but physics.formulation needs {expected}D")]
    MeshDimension { file: String, found: usize, expected: usize },
    #[error(transparent)]
    Flow(#[from] FlowError),
    #[error(transparent)]
    Solid(#[from] SolidError),
    #[error(transparent)]
    Fsi(#[from] FsiError),
    #[error("solid: {0}")]
    Adapt(#[from] AdaptError),
    #[error("solid: {0}")]
    SolidMesh(String),
}

/// A case error about the case file as a whole (the caller names the file).
fn invalid(message: String) -> SetupError {
    SetupError::Case(CaseError::Invalid { file: "case".into(), message })
}

/// Builds the case's fluid mesh.
pub fn build_mesh(case: &Case, case_dir: &Path) -> Result<AnyMesh, SetupError> {
    let spec = case.mesh.as_ref().ok_or_else(|| CaseError::Invalid { file: "case".into(), message: "the case has no fluid [mesh]".into() })?;
    Ok(match spec {
        MeshSpec::Rectangle { x, y, n } => {
            AnyMesh::D2(generate::rectangle_triangles(x[0], x[1], y[0], y[1], n[0], n[1], generate::DiagonalPattern::Alternating))
        }
        MeshSpec::Channel { length, height, n, grading } => AnyMesh::D2(generate::channel_triangles(*length, *height, n[0], n[1], *grading)),
        MeshSpec::Box { x, y, z, n } => AnyMesh::D3(generate::box_tetrahedra(x[0], x[1], y[0], y[1], z[0], z[1], n[0], n[1], n[2])),
        MeshSpec::Pipe { radius, length, n_radial, n_axial, quarter } => {
            AnyMesh::D3(generate::pipe_tetrahedra(*radius, *length, *n_radial, *n_axial, *quarter))
        }
        MeshSpec::Gmsh { file } => {
            let path = if file.is_absolute() { file.clone() } else { case_dir.join(file) };
            let mesh = read_msh(&path)?;
            let found = match &mesh {
                AnyMesh::D2(_) => 2,
                AnyMesh::D3(_) => 3,
            };
            if found != case.dim() {
                return Err(SetupError::MeshDimension { file: path.display().to_string(), found, expected: case.dim() });
            }
            mesh
        }
    })
}

/// The fluid mesh of a case: built, and adapted to the solid's surface when the case has one
/// (the facets on gamma_s then form the boundary `gamma_f`), with the counts of the adaptation.
pub fn fluid_mesh(case: &Case, case_dir: &Path) -> Result<(AnyMesh, Option<AdaptStats>), SetupError> {
    let mesh = build_mesh(case, case_dir)?;
    if case.solid.is_empty() {
        return Ok((mesh, None));
    }
    Ok(match mesh {
        AnyMesh::D2(m) => {
            let a = adapt_fluid(case, m, case_dir)?.adapted;
            (AnyMesh::D2(a.mesh), Some(a.stats))
        }
        AnyMesh::D3(m) => {
            let a = adapt_fluid(case, m, case_dir)?.adapted;
            (AnyMesh::D3(a.mesh), Some(a.stats))
        }
    })
}

/// A vector of compiled expressions, times a time function, as a field of position and time.
fn vector_fn<const D: usize>(exprs: Vec<Expr>, time: TimeFn) -> VectorFn<D> {
    Arc::new(move |x: &[f64; D], t: f64| {
        let s = time.eval(t);
        std::array::from_fn(|a| s * exprs[a].eval(x, t))
    })
}

/// The symmetry plane of the boundary `name` normal to `normal` (the case file's entries, one per
/// dimension), normalised.
fn symmetry_plane<const D: usize>(name: &str, normal: &[f64]) -> Result<SymmetryBc<D>, SetupError> {
    let n: [f64; D] = std::array::from_fn(|a| normal.get(a).copied().unwrap_or(0.0));
    SymmetryBc::new(name, n).ok_or_else(|| invalid(format!("boundary '{name}': the normal {normal:?} is not a direction")))
}

fn compile_all(values: &[crate::case::Scalar]) -> Result<Vec<Expr>, CaseError> {
    values.iter().map(|v| Expr::compile(v).map_err(|message| CaseError::Invalid { file: "case".into(), message })).collect()
}

/// The flow problem a case describes on `mesh`; time-function tables are read relative to
/// `case_dir`.
pub fn flow_problem<const D: usize>(case: &Case, mesh: &Mesh<D>, case_dir: &Path) -> Result<FlowProblem<D>, SetupError> {
    let mut dirichlet = Vec::new();
    let mut traction = Vec::new();
    let mut windkessel = Vec::new();
    let mut backflow = Vec::new();
    let mut symmetry = Vec::new();
    let all: Vec<usize> = (0..D).collect();
    let zero: VectorFn<D> = Arc::new(|_: &[f64; D], _| [0.0; D]);
    // Exterior facets whose normal velocity is not prescribed fix the pressure level.
    let mut pressure_fixed = false;
    let mut covered = 0usize;
    for b in &case.boundary {
        mesh.boundary_tag(&b.name).map_err(FlowError::from)?;
        let count = mesh.boundary_facets(&b.name).map_err(FlowError::from)?.len();
        let bc = |components: Vec<usize>, value: VectorFn<D>| DirichletBc { boundary: b.name.clone(), components, value };
        let time = match &b.time_function {
            Some(f) => TimeFn::load(f, case_dir)?,
            None => TimeFn::Constant,
        };
        if let Some(beta) = b.backflow_stabilization.filter(|&beta| beta > 0.0) {
            backflow.push(BackflowBc { boundary: b.name.clone(), beta });
        }
        // A traction boundary crossed normally: the other components held at 0.
        if let (Some(axis), BoundaryType::Pressure | BoundaryType::Free | BoundaryType::Windkessel) = (b.normal_axis, b.kind) {
            dirichlet.push(bc((0..D).filter(|&a| a != axis).collect(), zero.clone()));
        }
        match b.kind {
            BoundaryType::Velocity => {
                dirichlet.push(bc(all.clone(), vector_fn(compile_all(&b.value)?, time)));
                covered += count;
            }
            BoundaryType::NoSlip => {
                dirichlet.push(bc(all.clone(), zero.clone()));
                covered += count;
            }
            BoundaryType::Axis => {
                dirichlet.push(bc(vec![1], zero.clone()));
                covered += count;
            }
            BoundaryType::Symmetry => {
                // A plane normal to an axis holds that component; any other, `u . n = 0`.
                let plane = b.normal.as_deref().map(|n| symmetry_plane::<D>(&b.name, n)).transpose()?;
                match plane.as_ref().map_or(b.normal_axis, SymmetryBc::axis) {
                    Some(axis) => dirichlet.push(bc(vec![axis], zero.clone())),
                    None => symmetry.extend(plane),
                }
                covered += count;
            }
            BoundaryType::Traction => {
                let f = vector_fn::<D>(compile_all(&b.value)?, time);
                traction.push(TractionBc { boundary: b.name.clone(), traction: Arc::new(move |x, _n, t| f(x, t)) });
                pressure_fixed = true;
            }
            BoundaryType::Pressure => {
                let p = compile_all(&b.value)?.remove(0);
                traction.push(TractionBc {
                    boundary: b.name.clone(),
                    traction: Arc::new(move |x: &[f64; D], n: &[f64; D], t| {
                        let pv = time.eval(t) * p.eval(x, t);
                        std::array::from_fn(|a| -pv * n[a])
                    }),
                });
                pressure_fixed = true;
            }
            BoundaryType::Free => {
                // Traction-free, as by default; named so that it is known to set the pressure's
                // level (a closed valve's gap cuts off fluid that reaches no such boundary).
                traction.push(TractionBc { boundary: b.name.clone(), traction: Arc::new(|_: &[f64; D], _: &[f64; D], _| [0.0; D]) });
                pressure_fixed = true;
            }
            BoundaryType::Windkessel => {
                let w = b.windkessel.as_ref().ok_or_else(|| CaseError::Invalid {
                    file: "case".into(),
                    message: format!("boundary '{}': type = \"windkessel\" needs its windkessel table", b.name),
                })?;
                windkessel.push(WindkesselBc {
                    boundary: b.name.clone(),
                    proximal_resistance: w.proximal_resistance,
                    compliance: w.compliance,
                    distal_resistance: w.distal_resistance,
                    distal_pressure: w.distal_pressure,
                    initial_pressure: w.initial_pressure.unwrap_or(w.distal_pressure),
                });
                pressure_fixed = true;
            }
        }
    }
    let exterior = Topology::build(mesh).exterior_facets().len();
    if covered < exterior {
        pressure_fixed = true; // some boundary is traction-free by default
    }
    let body_force = match &case.body_force {
        Some(f) => Some(vector_fn::<D>(compile_all(f)?, TimeFn::Constant)),
        None => None,
    };
    let fluid = case.fluid.as_ref().ok_or_else(|| CaseError::Invalid { file: "case".into(), message: "the case has no [fluid] table".into() })?;
    Ok(FlowProblem {
        formulation: case.physics.formulation,
        params: FluidParams {
            viscosity: fluid.viscosity,
            density: fluid.density,
            inv_dt: 0.0,
            convection: case.physics.model == FlowModel::NavierStokes,
            convective_form: fluid.convective_form,
            viscous_form: fluid.viscous_form,
            stabilization: fluid.stabilization,
        },
        body_force,
        dirichlet,
        traction,
        windkessel,
        backflow,
        symmetry,
        pin_pressure: !pressure_fixed,
    })
}

/// The adaptation's options of a case's (first) solid: `eps_hat`, `min_move_quality`,
/// `boundary_cuts` and `min_cut_quality`.
pub fn adapt_options(spec: &crate::case::SolidSpec) -> AdaptOptions {
    AdaptOptions {
        eps_hat: spec.eps_hat,
        min_move_quality: spec.min_move_quality,
        touch_fixed_boundary: spec.boundary_cuts == crate::case::BoundaryCuts::Touch,
        min_cut_quality: spec.min_cut_quality,
    }
}

/// Adapts `fluid` to the case's solid and tags gamma_f on the adapted mesh (which then replaces
/// `adapted.mesh`'s boundary list with the parent's tags plus `gamma_f`).
pub fn adapt_fluid<const D: usize>(case: &Case, fluid: Mesh<D>, case_dir: &Path) -> Result<AdaptedFluid<D>, SetupError> {
    let covered = case.covered_fluid();
    adapt_fluid_with(case, fluid, case_dir, covered)
}

/// As [`adapt_fluid`], with the covered cells kept or removed as `covered` says.
pub fn adapt_fluid_with<const D: usize>(case: &Case, fluid: Mesh<D>, case_dir: &Path, covered: CoveredFluid) -> Result<AdaptedFluid<D>, SetupError> {
    let spec = case.first_solid().ok_or_else(|| SetupError::SolidMesh("the case has no [solid] table".into()))?;
    let solid = solid_mesh::<D>(case, case_dir)?.mesh;
    let name = case.solid_surface().ok_or_else(|| SetupError::SolidMesh("solid.surface is not set".into()))?;
    let surface = Surface::from_mesh_boundary(&solid, &name)?;
    let background = Background::new(&fluid)?;
    Ok(AdaptedFluid::new(fluid, &background, solid, surface, &adapt_options(spec), covered)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The adaptation's options of `[solid]` reach [`AdaptOptions`]; without them, the defaults
    /// of [`AdaptOptions::new`].
    #[test]
    fn the_solid_adaptation_options_reach_the_adaptation() {
        let base = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/malformed/ok-solid.toml")).unwrap();
        let options = |extra: &str| {
            let case = Case::from_toml_str(&base.replace("[solid]\n", &format!("[solid]\n{extra}")), "ok-solid.toml").unwrap();
            adapt_options(case.first_solid().unwrap())
        };
        let defaults = options("");
        assert_eq!((defaults.eps_hat, defaults.min_move_quality, defaults.touch_fixed_boundary, defaults.min_cut_quality), (0.2, 0.01, false, 0.0));
        let given = options("eps_hat = 0.3\nmin_move_quality = 0.001\nboundary_cuts = \"touch\"\nmin_cut_quality = 0.05\n");
        assert_eq!((given.eps_hat, given.min_move_quality, given.touch_fixed_boundary, given.min_cut_quality), (0.3, 0.001, true, 0.05));
        assert!(!options("boundary_cuts = \"split\"\n").touch_fixed_boundary);
    }

    /// `normal_axis` on a pressure inlet holds the other velocity components at 0 there (a
    /// Dirichlet condition on component 1 only); `backflow_stabilization` becomes a
    /// [`BackflowBc`]; neither is there without its key.
    #[test]
    fn a_pressure_inlet_crossed_normally_holds_its_tangential_velocity() {
        let text = |extra: &str| {
            format!(
                "title = \"t\"\n[mesh]\nkind = \"channel\"\nlength = 2.0\nheight = 1.0\nn = [4, 2]\n[physics]\nformulation = \"plane\"\n\
                 model = \"navier-stokes\"\n[fluid]\ndensity = 1.0\nviscosity = 0.01\n[[boundary]]\nname = \"inlet\"\ntype = \"pressure\"\n\
                 value = [1.0]\n{extra}\n[[boundary]]\nname = \"outlet\"\ntype = \"free\"\n"
            )
        };
        let problem = |extra: &str| {
            let case = Case::from_toml_str(&text(extra), "t.toml").unwrap();
            let AnyMesh::D2(mesh) = build_mesh(&case, Path::new(".")).unwrap() else { panic!("2D") };
            flow_problem::<2>(&case, &mesh, Path::new(".")).unwrap()
        };
        let plain = problem("");
        assert!(plain.dirichlet.iter().all(|bc| bc.boundary != "inlet") && plain.backflow.is_empty());
        let normal = problem("normal_axis = 0\nbackflow_stabilization = 0.5");
        let held: Vec<_> = normal.dirichlet.iter().filter(|bc| bc.boundary == "inlet").collect();
        assert_eq!(held.len(), 1);
        assert_eq!(held[0].components, vec![1]);
        assert_eq!((held[0].value)(&[0.0, 0.5], 0.3), [0.0, 0.0]);
        assert_eq!(normal.backflow, vec![BackflowBc { boundary: "inlet".into(), beta: 0.5 }]);
    }
}
