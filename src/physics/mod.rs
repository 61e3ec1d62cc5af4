//! Physics kernels: the fluid ([`fluid`]); the solid and the coupling join later.
pub mod coupling;
pub mod fluid;
pub mod solid;
