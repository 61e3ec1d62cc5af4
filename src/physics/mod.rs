//! Physics kernels: the fluid ([`fluid`]); the solid and the coupling join later.
pub mod fluid;
pub mod solid;
pub mod coupling;
