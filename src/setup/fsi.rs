//! The FSI model of a case: fluid and solid problems, the coupling surface and the multiplier
//! space.

use super::{flow_problem, invalid, SetupError};
use crate::case::Case;
use crate::discretize::fsi::{FsiModel, FsiProblem};
use fdfsi_fem::mesh::Mesh;

/// The FSI model of a case on its (original) fluid mesh; relative paths in the case are resolved
/// against `case_dir`.
pub fn fsi_model<const D: usize>(case: &Case, fluid_mesh: &Mesh<D>, case_dir: &std::path::Path) -> Result<FsiModel<D>, SetupError> {
    let spec = case.first_solid().ok_or_else(|| invalid("no [solid] table".into()))?;
    case.time.as_ref().ok_or_else(|| invalid("FSI runs need a [time] table".into()))?;
    let surface = case.solid_surface().ok_or_else(|| invalid("solid.surface is required with a fluid".into()))?;
    let fluid = flow_problem(case, fluid_mesh, case_dir)?;
    let solid_mesh = super::solid_mesh::<D>(case, case_dir)?;
    let solid = super::solid_problem::<D>(case, solid_mesh.cell_body, false)?;
    let problem = FsiProblem { fluid, solid, surface, adapt: super::adapt_options(spec) };
    // In the order of the problem's contacts: solid after solid.
    let cut_offs: Vec<Option<f64>> = case.solid.iter().flat_map(|s| &s.contact).map(|c| c.fluid_cut_off).collect();
    Ok(FsiModel::new(problem, fluid_mesh, solid_mesh.mesh)?
        .with_multiplier(spec.multiplier)
        .with_covered_fluid(spec.covered_fluid)
        .with_film_pressure(spec.film_pressure)
        .with_film_squeeze(spec.film_squeeze)
        .with_cut_offs(&cut_offs))
}
