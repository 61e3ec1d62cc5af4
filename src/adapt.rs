//! The fluid mesh adapted to the solid surface (paper section 2.2.1).
//!
//! Per step (and for `fdfsi adapt`): the solid mesh at its current position gives gamma_s
//! ([`fdfsi_fem::adapt::Surface`]); the ORIGINAL fluid mesh is adapted to it
//! ([`fdfsi_fem::adapt::adapt`]); the fluid facets on gamma_s become the boundary `gamma_f` of
//! the adapted mesh, so boundary conditions and quantities can name it; `gamma_f_minus` and
//! `gamma_f_plus` are the same facets seen from the fluid cells on either side (for one-sided
//! quantities such as the wall shear stress on both faces of a thin plate).

use fdfsi_fem::adapt::{adapt_with, AdaptError, AdaptOptions, Adapted, Background, Surface};
use fdfsi_fem::mesh::Mesh;

pub use fdfsi_fem::adapt::{GAMMA_F, GAMMA_F_MINUS, GAMMA_F_PLUS};

/// A fluid mesh adapted to a solid, with the facets on gamma_s tagged `gamma_f`.
pub struct AdaptedFluid<const D: usize> {
    pub original: Mesh<D>,
    pub solid: Mesh<D>,
    pub surface: Surface<D>,
    pub adapted: Adapted<D>,
}

impl<const D: usize> AdaptedFluid<D> {
    /// `original` (prepared as `background`) adapted to `surface`, the surface of `solid`, with
    /// gamma_f tagged on the adapted mesh.
    pub fn new(
        original: Mesh<D>,
        background: &Background<D>,
        solid: Mesh<D>,
        surface: Surface<D>,
        options: &AdaptOptions,
    ) -> Result<Self, AdaptError> {
        let mut adapted = adapt_with(background, &surface, options)?;
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
