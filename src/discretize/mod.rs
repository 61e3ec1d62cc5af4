//! Discretisation (paper sections 2.1-2.2): dof maps, sparsity patterns and assembly.
//!
//! - [`flow`]: the P2+/P1disc fluid on one mesh;
//! - [`solid`]: the Q2/P1disc (or Q2) solid, total or updated Lagrangian;
//! - [`fsi`]: the monolithic system of one FSI step and its coupling elements;
//! - [`layout`]: the named blocks of the monolithic system's unknowns;
//! - [`symmetry`]: symmetry planes of any normal (`u . n = 0`), for the fluid and the solid;
//! - [`time_scheme`]: implicit Euler and BDF2 as one formula, for the steppers and the FSI step.
pub mod flow;
pub mod fsi;
pub mod layout;
pub mod mortar;
pub mod solid;
pub mod symmetry;
pub mod time_scheme;

use fdfsi_fem::dofs::BlockLayout;

/// The unknowns of "cell" `c` of a system whose couplings are the mesh's cells of `layout`
/// (`c < num_cells`) and then the `extra` ones (a flow's Windkessel outlets, a solid's contact
/// nodes), into `buf`.
pub(crate) fn system_cell_dofs(layout: &BlockLayout, num_cells: usize, extra: &[Vec<usize>], c: usize, buf: &mut Vec<usize>) {
    if c < num_cells {
        layout.cell_dofs_into(c, buf)
    } else {
        buf.clear();
        buf.extend_from_slice(&extra[c - num_cells]);
    }
}
