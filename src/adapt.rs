//! The fluid mesh adapted to the solid surface (paper section 2.2.1).
//!
//! Per step (and for `fdfsi adapt`): the solid mesh at its current position gives gamma_s
//! ([`fdfsi_fem::adapt::Surface`]); the ORIGINAL fluid mesh is adapted to it
//! ([`fdfsi_fem::adapt::adapt`]); the fluid facets on gamma_s become the boundary `gamma_f` of
//! the adapted mesh, so boundary conditions and quantities can name it; `gamma_f_minus` and
//! `gamma_f_plus` are the same facets seen from the fluid cells on either side (for one-sided
//! quantities such as the wall shear stress on both faces of a thin plate). In 2D the corners
//! of gamma_s are made fluid vertices first; the fluid cells a closed gamma_f encloses are kept
//! or removed as [`CoveredFluid`] says.

use fdfsi_fem::adapt::{adapt_with, remove_enclosed, AdaptError, AdaptOptions, Adapted, Background, Surface};
use fdfsi_fem::mesh::Mesh;

pub use fdfsi_fem::adapt::{GAMMA_F, GAMMA_F_MINUS, GAMMA_F_PLUS};

/// What becomes of the fluid cells the solid covers.
///
/// The fluid mesh covers the solid (it is adapted to gamma_s, not cut out). With a slender solid
/// coupled on one face (the paper's model problems) the covered fluid stays in the fluid system:
/// it moves with the solid and carries its mass (`kept`, the paper's; default). A thick solid
/// wetted on its whole boundary encloses its covered cells by gamma_f (with the domain boundary,
/// where it is fixed to a wall): kept, that fictitious fluid is incompressible and holds the
/// solid's area (volume) fixed, which a compressible solid must be free to change. `removed`
/// takes those cells out of each step's adapted mesh ([`remove_enclosed`]):
/// the fluid then lies on one side of gamma_f only, and the solid's own density carries its
/// inertia. It needs a gamma_f that encloses the solid.
///
/// In case files (`[solid] covered_fluid`): `kept`, `removed`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CoveredFluid {
    /// The covered fluid stays (the paper's).
    #[default]
    Kept,
    /// The cells gamma_f encloses are removed from the fluid system.
    Removed,
}

impl CoveredFluid {
    /// `adapted` (adapted to `surface`) with the enclosed cells removed if so chosen.
    pub fn apply<const D: usize>(self, adapted: Adapted<D>, surface: &Surface<D>) -> Result<Adapted<D>, AdaptError> {
        match self {
            CoveredFluid::Kept => Ok(adapted),
            CoveredFluid::Removed => remove_enclosed(adapted, surface),
        }
    }
}

/// A fluid mesh adapted to a solid, with the facets on gamma_s tagged `gamma_f`.
pub struct AdaptedFluid<const D: usize> {
    pub original: Mesh<D>,
    pub solid: Mesh<D>,
    pub surface: Surface<D>,
    pub adapted: Adapted<D>,
}

impl<const D: usize> AdaptedFluid<D> {
    /// `original` (prepared as `background`) adapted to `surface`, the surface of `solid`, with
    /// the covered cells kept or removed and gamma_f tagged on the adapted mesh.
    pub fn new(
        original: Mesh<D>,
        background: &Background<D>,
        solid: Mesh<D>,
        surface: Surface<D>,
        options: &AdaptOptions,
        covered: CoveredFluid,
    ) -> Result<Self, AdaptError> {
        let mut adapted = covered.apply(adapt_with(background, &surface, options)?, &surface)?;
        fdfsi_fem::adapt::tag_gamma_f(&mut adapted.mesh, &adapted.gamma_f);
        Ok(AdaptedFluid { original, solid, surface, adapted })
    }
}

/// The adapted mesh with the gamma_f facets tagged as the boundary [`GAMMA_F`] (one side per
/// facet).
pub fn tag_gamma_f<const D: usize>(adapted: &Adapted<D>) -> Mesh<D> {
    let mut mesh = adapted.mesh.clone();
    fdfsi_fem::adapt::tag_gamma_f(&mut mesh, &adapted.gamma_f);
    mesh
}
