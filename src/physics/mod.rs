//! Physics kernels: the fluid ([`fluid`]), the solid ([`solid`]), their coupling ([`coupling`])
//! and the solid's contact with rigid planes ([`contact`]).
pub mod contact;
pub mod coupling;
pub mod fluid;
pub mod solid;
