//! `fdfsi-fem`: the physics-free finite-element toolbox of fdfsi.
//!
//! Modules, each using only those listed before it:
//! [`quadrature`] and [`element`] (reference cells, rules, tabulation) -> [`values`] (geometric
//! map per cell) -> [`mesh`] (cells, tags, topology) -> [`generate`] (structured meshes) ->
//! [`gmsh`] (MSH 4.1 import) -> [`dofs`] (dof maps) -> [`sparse`] (pattern, CSR matrix,
//! coloured assembly) -> [`vtk`] (`.vtu`/`.pvd` output and read-back).

pub mod adapt;
pub mod dofs;
pub mod element;
pub mod generate;
pub mod gmsh;
pub mod locate;
pub mod mesh;
pub mod quadrature;
pub mod sparse;
pub mod values;
pub mod vtk;
