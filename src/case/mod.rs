//! Case files: the TOML description of a run, typed and validated.
//!
//! Every table rejects unknown keys (`deny_unknown_fields`), so a misspelt key is an error with
//! its line and column, never silently ignored. [`Case::from_toml_str`] parses,
//! [`Case::validate`] (in `validate.rs`, one function per table) checks ranges; the mesh-dependent
//! checks (boundary names exist) happen when the run builds its mesh.
//!
//! ```toml
//! title = "Poiseuille flow in a channel"
//!
//! [mesh]
//! kind = "rectangle"          # rectangle | channel | box | pipe | gmsh
//! x = [0.0, 4.0]
//! y = [0.0, 1.0]
//! n = [16, 4]
//!
//! [physics]
//! formulation = "plane"       # plane | axisymmetric | 3d
//! model = "stokes"            # stokes | navier-stokes
//!
//! [fluid]
//! density = 1.0
//! viscosity = 1.0
//!
//! [[boundary]]
//! name = "left"
//! type = "velocity"           # velocity | no-slip | traction | pressure | axis | symmetry | free
//! value = ["4*y*(1-y)", 0]    # numbers or expressions of x, y, z (r = y), t
//!
//! [[output.probe]]
//! name = "centre_u"
//! field = "velocity"          # velocity | pressure
//! component = 0
//! point = [2.0, 0.5]
//! ```

use crate::physics::fluid::Formulation;
use crate::solve::augmented::{AlOptions, AugmentedLagrangian, Placement};
use crate::solve::krylov::KrylovOptions;
use crate::solve::linear::{FaerLu, LinearSolver, LinearSolverOptions};
use crate::solve::newton::NewtonOptions;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::Arc;
use thiserror::Error;

pub mod builtin;
mod validate;

/// `[solid]` (one table) or `[[solid]]` (several) as one list: a single solid is written back as
/// `[solid]`, so a case's `case.toml` (and its hash) does not change with the form.
mod one_or_many {
    use super::SolidSpec;
    use serde::de::value::{MapAccessDeserializer, SeqAccessDeserializer};
    use serde::de::{MapAccess, SeqAccess, Visitor};
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(solids: &[SolidSpec], s: S) -> Result<S::Ok, S::Error> {
        match solids {
            [one] => one.serialize(s),
            several => several.serialize(s),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<SolidSpec>, D::Error> {
        struct OneOrMany;
        impl<'de> Visitor<'de> for OneOrMany {
            type Value = Vec<SolidSpec>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a [solid] table or [[solid]] tables")
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<Self::Value, A::Error> {
                Ok(vec![SolidSpec::deserialize(MapAccessDeserializer::new(map))?])
            }
            fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<Self::Value, A::Error> {
                Vec::deserialize(SeqAccessDeserializer::new(seq))
            }
        }
        d.deserialize_any(OneOrMany)
    }
}

/// A case-file error.
#[derive(Debug, Error)]
pub enum CaseError {
    #[error("{file}: {message}")]
    Parse { file: String, message: String },
    #[error("{file}: {message}")]
    Invalid { file: String, message: String },
    #[error("{file}: cannot read: {source}")]
    Io { file: String, source: std::io::Error },
}

/// A run described by a case file.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Case {
    /// One-line title.
    pub title: String,
    /// Longer description: what the case shows, where its values come from.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    /// The fluid mesh; absent in a solid-only case.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh: Option<MeshSpec>,
    pub physics: PhysicsSpec,
    /// The fluid material; required with a fluid mesh.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fluid: Option<FluidSpec>,
    /// Boundary conditions, one table per named boundary.
    #[serde(default)]
    pub boundary: Vec<BoundarySpec>,
    /// Body force per unit volume, per component (numbers or expressions).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body_force: Option<Vec<Scalar>>,
    /// The solid immersed in the fluid: its mesh, placement and coupled surface gamma_s. One
    /// `[solid]` table, or several `[[solid]]` tables (each with a `name`: two leaflets), whose
    /// meshes are joined into one solid of several bodies (see [`Case::solid_boundary`]).
    #[serde(default, with = "one_or_many", skip_serializing_if = "Vec::is_empty")]
    pub solid: Vec<SolidSpec>,
    /// Time stepping; without it the problem is steady.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time: Option<TimeSpec>,
    #[serde(default)]
    pub solver: SolverSpec,
    #[serde(default)]
    pub output: OutputSpec,
}

/// One boundary name, or several that act as one boundary (their union).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(untagged)]
pub enum BoundaryNames {
    One(String),
    Several(Vec<String>),
}

impl BoundaryNames {
    /// The names given.
    pub fn names(&self) -> &[String] {
        match self {
            BoundaryNames::One(n) => std::slice::from_ref(n),
            BoundaryNames::Several(v) => v,
        }
    }

    /// The name of the union: the names joined by `+` (the name itself for one).
    pub fn joined(&self) -> String {
        self.names().join("+")
    }
}

impl std::fmt::Display for BoundaryNames {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.joined())
    }
}

/// The immersed solid.
///
/// Every run (and `fdfsi adapt`) adapts the fluid mesh to the solid's surface `surface`
/// (gamma_s), as in the paper's section 2.2.1, and names the fluid facets on it `gamma_f`, so
/// boundary conditions can be given there.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SolidSpec {
    /// The solid's name; required with several `[[solid]]` tables (non-empty, unique, without `/`
    /// or `+`). Their boundaries are then `NAME/BOUNDARY` wherever they are seen from outside
    /// their own table (contact quantities, `against` another solid). A single solid's names
    /// nothing.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The solid mesh (9-node quadrilaterals / 27-node hexahedra).
    pub mesh: SolidMeshSpec,
    /// The solid boundary coupled to the fluid (gamma_s): one name, or several (`["bottom",
    /// "tip", "top"]`: their union, e.g. the wetted sides of a thick solid); required when there
    /// is a fluid.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface: Option<BoundaryNames>,
    /// `fixed`: the solid does not move, and the fluid sees it only through the conditions given
    /// on the boundary `gamma_f` (e.g. no-slip: the paper's pure-fluid twin of model problem 2).
    /// The material laws are solved in solid-only cases (no fluid mesh).
    #[serde(default)]
    pub model: SolidModel,
    /// Shear modulus G (the Lame constant mu; material laws; > 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shear_modulus: Option<f64>,
    /// Bulk modulus K (> 0): omitted for the incompressible neo-Hookean law (det F = 1); required
    /// by the compressible laws.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bulk_modulus: Option<f64>,
    /// Young's modulus E: with one other elastic constant, instead of `shear_modulus` and
    /// `bulk_modulus` (see [`SolidSpec::moduli`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub youngs_modulus: Option<f64>,
    /// Poisson's ratio nu in (-1, 0.5): with one other elastic constant.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub poissons_ratio: Option<f64>,
    /// The first Lame constant lambda: with one other elastic constant.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lame_lambda: Option<f64>,
    /// Reference density rho_0 (>= 0): the solid's inertia `rho_0 d^2u/dt^2` per unit reference
    /// volume in time-dependent runs (solid-only and FSI); 0 (the default) leaves it out.
    #[serde(default)]
    pub density: f64,
    /// Body force per unit reference volume (e.g. gravity: `rho_0 g`), one entry per dimension:
    /// numbers or expressions of the reference position x, y, z and the time t (0 in
    /// quasi-static runs, where the force is ramped with the load factor).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body_force: Option<Vec<Scalar>>,
    /// One family of fibres reinforcing the material law (Holzapfel-Gasser-Ogden form, see
    /// [`crate::physics::solid::FibreReinforced`]): a valve leaflet's collagen.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fibres: Option<FibreSpec>,
    /// Boundary conditions of the solid.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub boundary: Vec<SolidBoundarySpec>,
    /// `[[solid.contact]]`: frictionless contact of solid boundaries with rigid planes.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub contact: Vec<ContactSpec>,
    /// Quasi-static load stepping: boundary values are multiplied by a load factor ramped from 0
    /// to 1.
    #[serde(default)]
    pub loading: LoadingSpec,
    /// The Lagrange multiplier on gamma_f (FSI runs): `p1-discontinuous` (the paper's; default)
    /// or `p1-discontinuous-trace-mode` (2D: adds, per component and connected piece of gamma_f,
    /// the P2 trace function the paper's multiplier leaves free, so that the fluid velocity on
    /// gamma_f equals the solid's at every node; see [`crate::discretize::fsi::MultiplierSpace`]).
    #[serde(default, skip_serializing_if = "is_default")]
    pub multiplier: crate::discretize::fsi::MultiplierSpace,
    /// The fluid cells the solid covers (FSI runs): `kept` (the paper's; default: a slender solid
    /// coupled on one face) or `removed` (a thick solid coupled on its whole wetted boundary,
    /// which gamma_f then encloses; a compressible solid is free to change its area; see
    /// [`crate::adapt::CoveredFluid`]).
    #[serde(default, skip_serializing_if = "is_default")]
    pub covered_fluid: crate::adapt::CoveredFluid,
    /// Whose pressure the film of blood in a gap a closed contact cut off carries (FSI runs with
    /// `[[solid.contact]]`): `nearest-mouth` (default: the fluid at the gap's mouth nearest each
    /// facet), `lowest-mouth` (the lowest of the gap's mouths at the step's start) or `reynolds`
    /// (the film's own pressure by Reynolds' equation on the gap, a mean of its mouths'; see
    /// [`crate::discretize::fsi::FilmPressure`]).
    #[serde(default, skip_serializing_if = "is_default")]
    pub film_pressure: crate::discretize::fsi::FilmPressure,
    /// With `film_pressure = "reynolds"`: the films' squeeze term too, `12 mu dh/dt` in
    /// Reynolds' equation (taken at each facet alone, a damper against the solid's motion normal to
    /// the film: [`crate::discretize::fsi::FilmLoad::squeeze`]); default false.
    #[serde(default, skip_serializing_if = "is_default")]
    pub film_squeeze: bool,
    /// The paper's eps_hat in (0, 0.5]: a cut closer than eps_hat |edge| to a node moves the node.
    #[serde(default = "default_eps_hat")]
    pub eps_hat: f64,
    /// A move of a fluid node onto gamma_s is refused (a new node is added on the cut edge
    /// instead) where a cell touching it would get a quality (1 = equilateral) below this, in
    /// (0, 1); default 0.01. A refused move pins the node, and the cuts on its other edges then
    /// cluster next to it: where gamma_s passes within a few hundredths of the edge length of many
    /// nodes (a curved leaflet in coarse tetrahedra), a smaller value trades a few cells of that
    /// quality for far worse slivers around the pinned nodes.
    #[serde(default = "default_min_move_quality", skip_serializing_if = "is_default_min_move_quality")]
    pub min_move_quality: f64,
    /// A cut of gamma_s within `eps_hat / 4` of a node on the fluid's boundary that may not move
    /// onto it (the cut lies off the node's boundary planes): `split` (default) adds a new node
    /// on the edge there, next to the boundary node; `touch` keeps the boundary node where it is
    /// and takes it to lie on gamma_s (gamma_f then passes through it, at most `eps_hat / 4` of
    /// an edge from gamma_s): no small cells where gamma_s meets the wall (a valve leaflet's
    /// attachment).
    #[serde(default, skip_serializing_if = "is_default")]
    pub boundary_cuts: BoundaryCuts,
    /// A new fluid node on an edge whose other end moved onto gamma_s is dropped (the edge then
    /// touches gamma_s at the moved node), where the chord between them runs along gamma_s, if a
    /// cell it makes with the moved node would have a quality below this, in [0, 1); no move is
    /// refused for it. Default 0: only below `min_move_quality`. Where gamma_s lies within
    /// hundredths of an edge of a plane of fluid nodes (a leaflet pressed on its plane of
    /// coaptation), such nodes make needle cells; 0.05 removes them.
    #[serde(default, skip_serializing_if = "is_default")]
    pub min_cut_quality: f64,
    /// Placement (2D): rotation in degrees (counter-clockwise) about `pivot`, then `translate`
    /// (finite numbers, one coordinate per dimension). The placed solid must lie inside the fluid
    /// mesh (`fdfsi check` locates every vertex of the solid mesh).
    #[serde(default)]
    pub rotate_deg: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pivot: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translate: Option<Vec<f64>>,
}

/// `[[solid.contact]]`: the solid boundary `boundary` may touch the rigid plane through `point`
/// with normal `normal` (pointing to the side the solid stays on), or (2D) the solid's boundary
/// `against`, without friction ([`crate::physics::contact`], [`crate::discretize::mortar`]).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ContactSpec {
    pub boundary: String,
    /// A point of the plane (one coordinate per dimension).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub point: Vec<f64>,
    /// The plane's normal (one entry per dimension; normalised).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub normal: Vec<f64>,
    /// Instead of a plane: another boundary of the solid (2D), the master of a mortar coupling;
    /// `boundary` carries the contact pressures. The two may lie on two bodies of one mesh.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub against: Option<String>,
    /// FSI runs: once the solid touches the plane (or the other boundary), the fluid between
    /// them is cut off where their gap is at most this length, so that a closed contact seals
    /// (see [`fdfsi_fem::adapt::gap`]). A length >= 0; 0 cuts nothing off. Default: for a plane
    /// the mean height of the fluid cells at the plane where it bounds the fluid (a wall, a
    /// symmetry line), 0 where it lies inside the fluid (a stop); against another boundary the
    /// mean size of the fluid cells at the contact boundary at rest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fluid_cut_off: Option<f64>,
}

/// `[solid.fibres]`: `Psi_f = k1 / (2 k2) (exp(k2 (I4 - 1)^2) - 1)` added to the law where the
/// fibres are stretched (`I4 = a_0 . C a_0 > 1`).
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct FibreSpec {
    /// Fibre stiffness k1 (a stress, > 0; small-strain fibre modulus `4 k1`).
    pub k1: f64,
    /// Fibre exponent k2 (dimensionless, >= 0; 0: the quadratic fibre `k1 / 2 (I4 - 1)^2`).
    #[serde(default)]
    pub k2: f64,
    /// The onset `delta` of `E = I4 - 1` over which the fibres engage smoothly, their tangent
    /// continuous (>= 0; default 0: at `I4 = 1` at once, the law as published, whose tangent jumps
    /// there; [`crate::physics::solid::FibreReinforced::fibre_derivatives`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub onset: Option<f64>,
    /// The fibre direction `a_0` in the reference configuration, one entry per dimension:
    /// numbers (a constant direction) or expressions of the reference position `x`, `y`, `z`
    /// (e.g. `["-y", "x"]`: circumferential about the z axis); normalised at every point.
    pub direction: Vec<Scalar>,
}

/// The shear and bulk moduli of a solid law.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Moduli {
    /// Shear modulus G (= mu).
    pub shear: f64,
    /// Bulk modulus K; `None` for an incompressible law.
    pub bulk: Option<f64>,
}

impl SolidSpec {
    /// The shear and bulk moduli from the elastic constants given: `shear_modulus` alone (an
    /// incompressible law) or any two of `shear_modulus` (G), `bulk_modulus` (K), `lame_lambda`
    /// (lambda), `youngs_modulus` (E) and `poissons_ratio` (nu), by the isotropic relations
    /// `K = lambda + 2 G / 3`, `E = 2 G (1 + nu) = 3 K (1 - 2 nu)`, `lambda = 2 G nu / (1 - 2 nu)`.
    /// Fails on any other count, or when the result is not `G > 0, K > 0` (`-1 < nu < 0.5`).
    pub fn moduli(&self) -> Result<Moduli, String> {
        let given = [
            ("shear_modulus", self.shear_modulus),
            ("bulk_modulus", self.bulk_modulus),
            ("lame_lambda", self.lame_lambda),
            ("youngs_modulus", self.youngs_modulus),
            ("poissons_ratio", self.poissons_ratio),
        ];
        let named: Vec<&str> = given.iter().filter(|(_, v)| v.is_some()).map(|(n, _)| *n).collect();
        if let Some((name, v)) = given.iter().find(|(_, v)| v.is_some_and(|v| !v.is_finite())) {
            return Err(format!("solid.{name} must be a finite number, got {}", v.unwrap_or(f64::NAN)));
        }
        let (g, k, l, e, nu) = (self.shear_modulus, self.bulk_modulus, self.lame_lambda, self.youngs_modulus, self.poissons_ratio);
        let (shear, bulk) = match (g, k, l, e, nu) {
            (Some(g), None, None, None, None) => (g, None),
            (Some(g), Some(k), None, None, None) => (g, Some(k)),
            (Some(g), None, Some(l), None, None) => (g, Some(l + 2.0 * g / 3.0)),
            (Some(g), None, None, Some(e), None) => (g, Some(e * g / (3.0 * (3.0 * g - e)))),
            (Some(g), None, None, None, Some(nu)) => (g, Some(2.0 * g * (1.0 + nu) / (3.0 * (1.0 - 2.0 * nu)))),
            (None, Some(k), Some(l), None, None) => (1.5 * (k - l), Some(k)),
            (None, Some(k), None, Some(e), None) => (3.0 * k * e / (9.0 * k - e), Some(k)),
            (None, Some(k), None, None, Some(nu)) => (3.0 * k * (1.0 - 2.0 * nu) / (2.0 * (1.0 + nu)), Some(k)),
            (None, None, Some(l), Some(e), None) => {
                let r = (e * e + 9.0 * l * l + 2.0 * e * l).sqrt();
                ((e - 3.0 * l + r) / 4.0, Some((e + 3.0 * l + r) / 6.0))
            }
            (None, None, Some(_), None, Some(0.0)) => {
                return Err("solid: lame_lambda and poissons_ratio = 0 do not determine the shear modulus; give another pair".into())
            }
            (None, None, Some(l), None, Some(nu)) => (l * (1.0 - 2.0 * nu) / (2.0 * nu), Some(l * (1.0 + nu) / (3.0 * nu))),
            (None, None, None, Some(e), Some(nu)) => (e / (2.0 * (1.0 + nu)), Some(e / (3.0 * (1.0 - 2.0 * nu)))),
            _ => {
                let got = if named.is_empty() { "none".to_string() } else { named.join(", ") };
                return Err(format!(
                    "solid: give shear_modulus alone (incompressible) or two of shear_modulus, bulk_modulus, lame_lambda, youngs_modulus, poissons_ratio; got {got}"
                ));
            }
        };
        let admissible = |v: f64| v > 0.0 && v.is_finite();
        if !admissible(shear) || bulk.is_some_and(|k| !admissible(k)) || nu.is_some_and(|nu| !(nu > -1.0 && nu < 0.5)) {
            return Err(format!(
                "solid: {} give shear modulus {shear:.6e} and bulk modulus {}: both must be positive and finite (Poisson's ratio in (-1, 0.5))",
                named.join(" and "),
                bulk.map_or("none".into(), |k| format!("{k:.6e}"))
            ));
        }
        Ok(Moduli { shear, bulk })
    }
}

fn is_default<T: Default + PartialEq>(v: &T) -> bool {
    *v == T::default()
}

/// What becomes of a cut of gamma_s next to a fluid boundary node that may not move onto it
/// ([`SolidSpec::boundary_cuts`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BoundaryCuts {
    /// A new node on the cut edge (the default).
    #[default]
    Split,
    /// The boundary node, where it is, taken to lie on gamma_s.
    Touch,
}

fn default_eps_hat() -> f64 {
    0.2
}

fn default_min_move_quality() -> f64 {
    0.01
}

/// Left out of the written case at its default, so that a case written before the key existed
/// (a checkpoint's) reads back as the same text.
fn is_default_min_move_quality(v: &f64) -> bool {
    *v == default_min_move_quality()
}

/// How the solid behaves.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SolidModel {
    /// Rigid and at rest.
    #[default]
    Fixed,
    /// The paper's law `sigma = G (F F^T - I) - p I`, mixed Q2/P1disc; incompressible
    /// (`det F = 1`) without `bulk_modulus`, nearly incompressible with it.
    NeoHookean,
    /// Compressible neo-Hookean (displacement only; needs `bulk_modulus`).
    NeoHookeanCompressible,
    /// Saint Venant-Kirchhoff (displacement only; needs `bulk_modulus`).
    SaintVenantKirchhoff,
}

/// A boundary condition of the solid; values are multiplied by the load factor.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SolidBoundarySpec {
    pub name: String,
    #[serde(rename = "type")]
    pub kind: SolidBoundaryType,
    /// Displacement or traction components (numbers or expressions of the reference position
    /// x, y, z), or the pressure (one entry).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub value: Vec<Scalar>,
    /// For `displacement`: the components prescribed (default: all).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub components: Option<Vec<usize>>,
    /// For `symmetry` (required): the plane's normal, one entry per dimension (normalised; any
    /// direction, e.g. `[-0.8660254037844386, 0.5, 0.0]` for the plane at 60 degrees about z
    /// of a valve sector). The boundary's facets must all be normal to it (to 1e-6).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal: Option<Vec<f64>>,
}

/// Kinds of solid boundary condition.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SolidBoundaryType {
    /// Prescribed total displacement.
    Displacement,
    /// Dead-load nominal traction (per unit reference area).
    Traction,
    /// Follower pressure on the deformed surface.
    Pressure,
    /// A roller on a plane: `u . n = 0` (the displacement normal to the plane `normal` held at
    /// 0, the tangential free), held exactly at every node of the boundary (also where it meets
    /// another plane: on their line only the motion along it is free). A normal along a
    /// coordinate axis is `displacement` with that one component 0.
    Symmetry,
}

/// Load stepping of a quasi-static solid run.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LoadingSpec {
    /// Number of equal load increments (each is halved on failure, down to 1/64 of it); 1 to
    /// [`MAX_STEPS`].
    #[serde(default = "one_usize")]
    pub steps: usize,
    /// `total` or `updated` (the paper's updated-Lagrangian form).
    #[serde(default = "updated")]
    pub mode: crate::discretize::solid::Lagrangian,
}

fn updated() -> crate::discretize::solid::Lagrangian {
    crate::discretize::solid::Lagrangian::Updated
}

impl Default for LoadingSpec {
    fn default() -> Self {
        LoadingSpec { steps: 1, mode: updated() }
    }
}

/// Solid meshes: quadratic quadrilaterals (2D) or hexahedra (3D).
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum SolidMeshSpec {
    /// `[x0, x1] x [y0, y1]` in `n[0] x n[1]` 9-node quadrilaterals; boundaries `left`, `right`,
    /// `bottom`, `top`.
    Rectangle { x: [f64; 2], y: [f64; 2], n: [usize; 2] },
    /// The bilinear image of the unit square with corners `corners` (counter-clockwise) in
    /// `n[0] x n[1]` 9-node quadrilaterals (e.g. Cook's membrane); boundaries `bottom` (corners
    /// 0-1), `right` (1-2), `top` (2-3), `left` (3-0).
    Quadrilateral { corners: [[f64; 2]; 4], n: [usize; 2] },
    /// Box in `n` 27-node hexahedra; boundaries `xmin` ... `zmax`.
    Box { x: [f64; 2], y: [f64; 2], z: [f64; 2], n: [usize; 3] },
    /// Quarter disc `x, y >= 0`, `x^2 + y^2 <= radius^2`, `z` in `[z0, z1]` in 27-node hexahedra:
    /// a membrane across a quarter `pipe` (see [`fdfsi_fem::generate::quarter_disc_hexahedra`]).
    /// A core block of `n_core x n_core` cells and two outer blocks of `n_core x n_ring`;
    /// `n_layers` (default 1) through the thickness. The rim is the polygon of `2 n_core` equal
    /// segments: with `2 n_core` equal to the pipe's wall segments (`round(1.5 n_radial)`) it is
    /// the pipe's wall. Boundaries `zmin`, `zmax`, `wall`, `symmetry_x`, `symmetry_y`.
    QuarterDisc {
        radius: f64,
        z: [f64; 2],
        n_core: usize,
        n_ring: usize,
        #[serde(default = "one_usize")]
        n_layers: usize,
    },
    /// A Gmsh file of 9-node quadrilaterals or 27-node hexahedra.
    Gmsh { file: PathBuf },
}

/// Time stepping of an unsteady run.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TimeSpec {
    /// Time step (> 0, finite); `end / dt` is at most [`MAX_STEPS`].
    pub dt: f64,
    /// End time (> 0, finite); the run starts at t = 0 from rest.
    pub end: f64,
    /// `euler` (implicit Euler, the paper's; default) or `bdf2`.
    #[serde(default)]
    pub scheme: crate::time::TimeScheme,
    /// Write the fields every this many steps (>= 1; the last step is always written).
    #[serde(default = "one_usize")]
    pub output_every: usize,
    /// The most times a step whose Newton solve fails may be halved, from where it failed on
    /// (the sub-steps done before stand), down to `dt / 2^max_cuts`, before the run stops (at
    /// most [`MAX_CUTS`]).
    #[serde(default = "four")]
    pub max_cuts: usize,
}

fn one_usize() -> usize {
    1
}
fn four() -> usize {
    4
}

/// A function of time multiplying a boundary value.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum TimeFunction {
    /// 1.
    Constant,
    /// `min(t / duration, 1)`; `duration > 0`.
    Ramp { duration: f64 },
    /// `sin(2 pi t / period + phase)`; `period > 0`.
    Sine {
        period: f64,
        #[serde(default)]
        phase: f64,
    },
    /// `sin(pi t / (2 rise))` for `t < rise`, then 1 (the first quarter of a sine, then held);
    /// `rise > 0`.
    QuarterSineHold { rise: f64 },
    /// Linear interpolation in a CSV file of `t,value` rows (a header line is allowed; finite
    /// numbers, `t` strictly increasing), held constant outside its range. Path relative to the
    /// case file. With `period` (> 0), the table repeats: the value at `t` is the table's at
    /// `t - period floor(t / period)` (a cardiac cycle's waveform over several beats).
    Table {
        file: PathBuf,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        period: Option<f64>,
    },
}

/// The fluid mesh: a built-in generator or a Gmsh file.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum MeshSpec {
    /// `[x0, x1] x [y0, y1]` in `n[0] x n[1]` squares, each split into two triangles (alternating
    /// diagonals). Boundaries `left`, `right`, `bottom`, `top`. Intervals increasing and finite,
    /// counts >= 1, at most [`MAX_GENERATED_CELLS`] cells (also for the other generators).
    Rectangle { x: [f64; 2], y: [f64; 2], n: [usize; 2] },
    /// Channel `[0, length] x [0, height]`, x-spacing fine in the middle and coarse towards both
    /// ends (`grading` = ratio of the largest to the smallest cell, 1 = uniform). Boundaries
    /// `inlet`, `outlet`, `bottom`, `top`. `length`, `height`, `grading` > 0.
    Channel {
        length: f64,
        height: f64,
        n: [usize; 2],
        #[serde(default = "one")]
        grading: f64,
    },
    /// Box `[x0,x1] x [y0,y1] x [z0,z1]`, each hexahedral cell split into six tetrahedra.
    /// Boundaries `xmin`, `xmax`, `ymin`, `ymax`, `zmin`, `zmax`.
    Box { x: [f64; 2], y: [f64; 2], z: [f64; 2], n: [usize; 3] },
    /// Circular pipe along z of straight-sided tetrahedra (or a quarter with symmetry planes).
    /// Boundaries `inlet` (z = 0), `outlet`, `wall`, and `symmetry_x`, `symmetry_y` when quarter.
    /// `radius`, `length` > 0; `n_radial`, `n_axial` >= 1.
    Pipe {
        radius: f64,
        length: f64,
        n_radial: usize,
        n_axial: usize,
        #[serde(default)]
        quarter: bool,
    },
    /// A Gmsh MSH 4.1 file (path relative to the case file); boundary and region names are its
    /// physical names. Second-order (curved) triangles and tetrahedra are used isoparametrically.
    Gmsh { file: PathBuf },
}

fn one() -> f64 {
    1.0
}

/// The equations.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PhysicsSpec {
    pub formulation: Formulation,
    #[serde(default)]
    pub model: FlowModel,
}

/// Stokes or (steady) Navier-Stokes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum FlowModel {
    #[default]
    Stokes,
    NavierStokes,
}

/// Fluid material.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct FluidSpec {
    /// Density rho (> 0).
    pub density: f64,
    /// Dynamic viscosity eta (> 0).
    pub viscosity: f64,
    /// `stress` (default, the paper's: natural condition sigma n = t) or `laplace` (natural
    /// condition eta du/dn - p n = t: the "do-nothing" outlet of the Schaefer-Turek benchmarks).
    #[serde(default)]
    pub viscous_form: crate::physics::fluid::ViscousForm,
    /// `convective` (default, the paper's: `rho u . grad u`) or `skew-symmetric` (adds
    /// `rho / 2 (div u) u`, zero for the exact solution, so that the discrete convection cannot
    /// feed kinetic energy inside the fluid: flows at high cell Reynolds numbers; see
    /// [`crate::physics::fluid::ConvectiveForm`]).
    #[serde(default, skip_serializing_if = "is_default")]
    pub convective_form: crate::physics::fluid::ConvectiveForm,
    /// `none` (default, the paper's Galerkin method) or `supg` (Navier-Stokes:
    /// streamline-upwind/Petrov-Galerkin, consistent, for flows whose cell Reynolds number is
    /// large; see [`crate::physics::fluid::Stabilization`]).
    #[serde(default, skip_serializing_if = "is_default")]
    pub stabilization: crate::physics::fluid::Stabilization,
}

/// A number or an expression of `x, y, z, r, t` (exmex syntax: `+ - * / ^`, `sin`, `cos`,
/// `exp`, `sqrt`, `PI`, ...).
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(untagged)]
pub enum Scalar {
    Number(f64),
    Expression(String),
}

/// Kinds of boundary condition.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum BoundaryType {
    /// Prescribed velocity `value` (one entry per component).
    Velocity,
    /// Zero velocity.
    NoSlip,
    /// Prescribed traction `sigma n = value`.
    Traction,
    /// Prescribed normal stress: `sigma n = -value n` (a pressure `value`).
    Pressure,
    /// Symmetry axis of an axisymmetric run (`r = 0`): radial velocity zero.
    Axis,
    /// Symmetry plane / free slip: normal velocity zero, `u . n = 0`. The plane is normal to a
    /// coordinate axis (`normal_axis`, 0-based: a Dirichlet condition on that component) or to
    /// any direction (`normal`: the constraint held exactly at every velocity node of the
    /// boundary by row operations on the system, [`crate::discretize::symmetry`]; two planes
    /// that meet leave only the velocity along their line free there).
    Symmetry,
    /// Traction-free ("do nothing").
    Free,
    /// A three-element Windkessel (RCR) outlet: the outlet pressure `R_p Q + P_c` as a normal
    /// stress, coupled implicitly to the flux `Q` and the capacitor pressure `P_c` (the
    /// boundary's `windkessel` table; see [`crate::discretize::flow::WindkesselBc`]).
    Windkessel,
}

/// `windkessel = { ... }` of a `type = "windkessel"` boundary: `C dP_c/dt = Q - (P_c - P_d)/R_d`,
/// outlet pressure `P = R_p Q + P_c`, in the case's units (SI: Pa s/m^3 and m^3/Pa in 3D and
/// axisymmetric; per unit depth in plane runs).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct WindkesselSpec {
    /// Proximal (characteristic) resistance R_p (>= 0).
    pub proximal_resistance: f64,
    /// Compliance C (>= 0; 0: two resistances in series).
    pub compliance: f64,
    /// Distal (peripheral) resistance R_d (> 0).
    pub distal_resistance: f64,
    /// Distal (venous) pressure P_d (default 0).
    #[serde(default)]
    pub distal_pressure: f64,
    /// The capacitor pressure P_c at the start of a run (default: `distal_pressure`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial_pressure: Option<f64>,
}

/// One boundary condition.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BoundarySpec {
    /// The boundary's name in the mesh.
    pub name: String,
    #[serde(rename = "type")]
    pub kind: BoundaryType,
    /// Velocity or traction components, or the pressure (one entry); numbers must be finite.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub value: Vec<Scalar>,
    /// For `symmetry`: the coordinate axis the plane is normal to. For `pressure`, `free` and
    /// `windkessel` (optional): the axis the boundary is normal to (not checked against its
    /// facets), across which the fluid then flows normally (its other velocity components held
    /// at 0): a traction inlet or outlet at a high Reynolds number otherwise lets fluid in
    /// sideways, which grows without bound at the corners with a wall. At a node shared with
    /// another Dirichlet boundary the first one in the case file sets a component.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal_axis: Option<usize>,
    /// For `symmetry`, instead of `normal_axis`: the plane's normal, one entry per dimension
    /// (normalised; any direction, e.g. `[-0.8660254037844386, 0.5, 0.0]` for the plane at 60
    /// degrees about z of a valve sector). The boundary's facets must all be normal to it (to
    /// 1e-6).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal: Option<Vec<f64>>,
    /// Multiplies `value` (unsteady runs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_function: Option<TimeFunction>,
    /// For `windkessel`: its constants.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub windkessel: Option<WindkesselSpec>,
    /// For `pressure`, `traction`, `free` and `windkessel` (Navier-Stokes): the backflow
    /// stabilisation `beta` in [0, 1] (default 0, none): the traction gains
    /// `beta rho / 2 min(u . n, 0) u`, which cancels the kinetic energy the entering fluid brings
    /// (see [`crate::discretize::flow::BackflowBc`]). With beta = 1 on an inlet crossed normally,
    /// a pressure there is the total pressure of a chamber at rest upstream.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub backflow_stabilization: Option<f64>,
}

/// Solver options.
#[derive(Clone, Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    #[serde(default)]
    pub newton: NewtonOptions,
    #[serde(default)]
    pub linear: LinearSpec,
    /// `[solver.petsc]`: the options of `method = "petsc"`.
    #[serde(default)]
    pub petsc: PetscSpec,
}

/// Options of `[solver.linear] method = "petsc"` (`[solver.petsc]`; the `petsc` cargo feature).
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct PetscSpec {
    /// PETSc options for fdfsi's `KSP` (prefix `fdfsi_`), added after the defaults (a direct
    /// solve by MUMPS: `-fdfsi_ksp_type preonly -fdfsi_pc_type lu
    /// -fdfsi_pc_factor_mat_solver_type mumps`), e.g. `"-fdfsi_mat_mumps_icntl_14 50"`. An
    /// iterative method chosen here must reach `|b - A x| <= 1e-6 |b|` in every solve (fdfsi's
    /// check; PETSc's default `-ksp_rtol` is 1e-5).
    pub options: String,
    /// What PETSc does with each system before `options`.
    pub solver: PetscMethod,
}

/// What `method = "petsc"` does with each system (`[solver.petsc] solver`).
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum PetscMethod {
    /// A direct solve by MUMPS (`crate::solve::petsc::DEFAULT_OPTIONS`).
    #[default]
    Mumps,
    /// FGMRES with the augmented-Lagrangian preconditioner of `method = "augmented-lagrangian"`
    /// (its `gamma` and placements from `[solver.linear]`) as PETSc's field split, the augmented
    /// block by MUMPS (`crate::solve::petsc::AUGMENTED_LAGRANGIAN_OPTIONS`). Verified on 2D flow,
    /// 2D and 3D FSI (Schaefer-Turek 2D-1, model problems 3 and 4, on 1 and 2 ranks).
    AugmentedLagrangian,
}

/// The linear solver of each Newton iteration (`[solver.linear] method`).
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum LinearMethod {
    /// Sparse LU of the whole saddle-point system.
    Direct,
    /// The default: FGMRES with the augmented-Lagrangian block preconditioner ([`crate::solve::augmented`]):
    /// an LU of the augmented primal block only. Flow runs: the pressure is the multiplier
    /// block; FSI runs: the fluid pressure, and in 3D also the coupling multiplier
    /// (`coupling_multipliers`); the solid pressure stays primal unless `solid_pressure =
    /// "schur"`; solid runs use the direct solver. On the shipped flow and FSI cases
    /// (BENCHMARKS.md, "The default linear solver") it takes 0.28-0.84x the direct solve's
    /// time from 8 000 unknowns up and half the memory on the large ones; the smallest take
    /// 0.03-0.36 s either way, but for the 1 000 steps of the 226-unknown Womersley case (1.2 s
    /// against 0.7 s).
    #[default]
    AugmentedLagrangian,
    /// PETSc's `KSP` on the whole system (an fdfsi built with the `petsc` cargo feature):
    /// by default a direct solve by MUMPS, anything else by `[solver.petsc] options`
    /// (`crate::solve::petsc`).
    Petsc,
}

/// Options of the linear solver (`[solver.linear]`).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct LinearSpec {
    /// `"direct"` or `"augmented-lagrangian"`.
    pub method: LinearMethod,
    /// Threads of the LU's large dense blocks: 1 (default) = sequential, 0 = all cores.
    pub threads: usize,
    /// Augmented Lagrangian: the dimensionless weight of the grad-div term.
    pub gamma: f64,
    /// Augmented Lagrangian: FGMRES stops at `|b - A x| <= krylov_tolerance |b|`.
    pub krylov_tolerance: f64,
    /// Augmented Lagrangian: most FGMRES iterations per linear solve.
    pub krylov_max_iterations: usize,
    /// Augmented Lagrangian: keep the factorisation of the augmented block across Newton
    /// iterations and steps, tried for at most this many Krylov iterations before the matrix is
    /// factorised (0: factorise at every Newton iteration). Unset:
    /// [`TIME_DEPENDENT_REFACTOR_ITERATIONS`] for time-dependent runs, 0 for steady ones.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refactor_iterations: Option<usize>,
    /// Augmented Lagrangian: where the multiplier groups (cells, facets) coupled to a
    /// Dirichlet-constrained unknown go: `"primal"` (the LU block) or `"schur"` (the Schur
    /// block with a reduced grad-div weight). Unset: `"schur"` in 3D, `"primal"` otherwise
    /// ([`crate::solve::augmented`], "Groups at Dirichlet boundaries").
    #[serde(skip_serializing_if = "Option::is_none")]
    pub boundary_multipliers: Option<Placement>,
    /// Augmented Lagrangian, FSI runs: where the coupling multiplier goes: `"primal"` (the LU
    /// block) or `"schur"` (the Schur block with a reduced grad-div weight). Unset: `"schur"` in
    /// 3D, `"primal"` otherwise ([`crate::solve::augmented`], "The solid's blocks").
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coupling_multipliers: Option<Placement>,
    /// Augmented Lagrangian, FSI runs with a mixed solid law: where the solid pressure goes,
    /// `"primal"` (unset: the held factors then serve a whole time step) or `"schur"`
    /// ([`crate::solve::augmented`], "The solid's blocks").
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solid_pressure: Option<Placement>,
}

/// The default `refactor_iterations` of time-dependent runs: the Jacobian changes little from
/// step to step (Schaefer-Turek 2D-2: one factorisation for its first 10 steps at 5.5-9 Krylov
/// iterations per Newton step; model problem 4 with the fluid pressure alone in the Schur block:
/// one per step, 3 steps in 54 s against 78 s; with the coupling multiplier too, the 3D
/// default: still one per step, 3 steps in 33 s).
pub const TIME_DEPENDENT_REFACTOR_ITERATIONS: usize = 8;

impl Default for LinearSpec {
    fn default() -> Self {
        let al = AlOptions::default();
        LinearSpec {
            method: LinearMethod::default(),
            threads: 1,
            gamma: al.gamma,
            krylov_tolerance: al.krylov.rel_tol,
            krylov_max_iterations: al.krylov.max_iterations,
            refactor_iterations: None,
            boundary_multipliers: None,
            coupling_multipliers: None,
            solid_pressure: None,
        }
    }
}

impl LinearSpec {
    /// The augmented-Lagrangian options of these settings, with the defaults of a
    /// time-dependent or steady run in `formulation` filled in.
    pub fn al_options(&self, time_dependent: bool, formulation: Formulation) -> AlOptions {
        let krylov = KrylovOptions { rel_tol: self.krylov_tolerance, max_iterations: self.krylov_max_iterations, ..Default::default() };
        let default_refactor = if time_dependent { TIME_DEPENDENT_REFACTOR_ITERATIONS } else { 0 };
        // The Schur block pays in 3D, where the LU of the augmented block dominates.
        let default_placement = if formulation == Formulation::ThreeD { Placement::Schur } else { Placement::Primal };
        AlOptions {
            gamma: self.gamma,
            krylov,
            refactor_iterations: self.refactor_iterations.unwrap_or(default_refactor),
            lu: self.lu_options(),
            boundary: self.boundary_multipliers.unwrap_or(default_placement),
            solid_pressure: self.solid_pressure.unwrap_or(Placement::Primal),
            coupling: self.coupling_multipliers.unwrap_or(default_placement),
        }
    }

    fn lu_options(&self) -> LinearSolverOptions {
        LinearSolverOptions { threads: self.threads, ..Default::default() }
    }
}

impl SolverSpec {
    /// The linear solver of these options, for a time-dependent run or a steady one in
    /// `formulation`.
    pub fn linear_solver(&self, time_dependent: bool, formulation: Formulation) -> Box<dyn LinearSolver> {
        match self.linear.method {
            LinearMethod::Direct => Box::new(FaerLu::new(self.linear.lu_options())),
            LinearMethod::AugmentedLagrangian => Box::new(AugmentedLagrangian::new(self.linear.al_options(time_dependent, formulation))),
            LinearMethod::Petsc => petsc_solver(&self.petsc, self.linear.al_options(time_dependent, formulation)),
        }
    }
}

#[cfg(feature = "petsc")]
fn petsc_solver(spec: &PetscSpec, al: AlOptions) -> Box<dyn LinearSolver> {
    use crate::solve::petsc::PetscSolver;
    let fail = LinearSolverOptions::default().fail_tolerance;
    match spec.solver {
        PetscMethod::Mumps => Box::new(PetscSolver::new(&spec.options, fail)),
        PetscMethod::AugmentedLagrangian => Box::new(PetscSolver::augmented_lagrangian(al, &spec.options, fail)),
    }
}

/// Without the `petsc` feature: a solver whose every factorisation fails, saying how to get one
/// (a validated case never asks for it: [`Case::validate`] refuses `method = "petsc"` there).
#[cfg(not(feature = "petsc"))]
fn petsc_solver(_spec: &PetscSpec, _al: AlOptions) -> Box<dyn LinearSolver> {
    use crate::solve::linear::{LinearSolveError, SolveStats};
    use fdfsi_fem::sparse::CscMatrix;
    struct WithoutPetsc;
    impl LinearSolver for WithoutPetsc {
        fn factorize(&mut self, _a: &CscMatrix<'_>) -> Result<(), LinearSolveError> {
            Err(LinearSolveError::Petsc(WITHOUT_PETSC.into()))
        }
        fn solve_in_place(&self, _a: &CscMatrix<'_>, _rhs: &mut [f64]) -> Result<SolveStats, LinearSolveError> {
            Err(LinearSolveError::Petsc(WITHOUT_PETSC.into()))
        }
        fn symbolic_factorizations(&self) -> usize {
            0
        }
    }
    Box::new(WithoutPetsc)
}

/// Why `method = "petsc"` fails in a build without the feature.
pub const WITHOUT_PETSC: &str =
    "this fdfsi was built without the petsc feature: install PETSc (Debian: apt install petsc-dev) and build with cargo build --release --features petsc";

/// What to write besides the fields.
#[derive(Clone, Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Time-dependent runs with a fluid: draw `animation.gif` of the speed at every output
    /// time at the end of the run ([`crate::io::animation`]); default true.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub animation: Option<bool>,
    /// 3D runs with a fluid: the plane of `speed.png` (default: see [`SliceSpec`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slice: Option<SliceSpec>,
    /// Point values of a field, written as quantities.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub probe: Vec<ProbeSpec>,
    /// Integrals over a boundary: `flux`, `mean-pressure`, `force`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub boundary_integral: Vec<BoundaryIntegralSpec>,
    /// Profiles along a boundary, written at the end of the run to `profiles/NAME.csv`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub profile: Vec<ProfileSpec>,
    /// Quantities of the fluid domain (or of a slab of it): `max-speed`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub domain: Vec<DomainQuantitySpec>,
    /// Linear combinations of other quantities (evaluated after them, in file order).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub combination: Vec<CombinationSpec>,
    /// Periodic quantities: mean, amplitude and frequency of their last period, written to
    /// `summary.json` at the end of a time-dependent run.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub oscillation: Vec<OscillationSpec>,
    /// Per-cycle statistics of a periodically driven run (a valve over cardiac cycles), written
    /// to `summary.json` at the end of a time-dependent run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cycles: Option<CyclesSpec>,
    /// 3D FSI runs: the valve's geometric orifice area, the quantity `open_area`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub open_area: Option<OpenAreaSpec>,
}

/// `[output.open_area]` (3D FSI runs): the quantity `open_area`, the area of the fluid mesh's
/// section by the plane `AXIS = at` that the solid's surface gamma_s, seen along `AXIS`, leaves
/// open ([`crate::post::open_area`]: the geometric orifice area of a valve), times `scale`
/// (e.g. 6 for a sixth of a valve).
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct OpenAreaSpec {
    /// The axis of the flow through the valve.
    pub axis: Axis,
    /// Where the plane of the section cuts that axis (e.g. at the annulus).
    pub at: f64,
    /// A factor on the area (> 0, default 1).
    #[serde(default = "one")]
    pub scale: f64,
}

/// `[output.cycles]`: the statistics of every whole cycle `K` (1-based) of `period` from `start`
/// ([`crate::post::cycles`]), written to `summary.json` as `cycle_K_forward_volume`,
/// `cycle_K_backward_volume`, `cycle_K_leak_volume`, `cycle_K_closing_time`,
/// `cycle_K_opening_time` (from the cycle's start), `cycle_K_peak_QUANTITY`,
/// `cycle_K_forward_peak_QUANTITY` and `cycle_K_forward_mean_QUANTITY`.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CyclesSpec {
    /// The period (> 0), e.g. the cardiac cycle's.
    pub period: f64,
    /// When the first cycle starts (>= 0; default 0): cycle `K` spans
    /// `[start + (K - 1) period, start + K period]`. A valve's cycles from mid-diastole each
    /// hold one opening and one closing, however these shift from beat to beat.
    #[serde(default)]
    pub start: f64,
    /// The flux through the valve, forward positive: a quantity of the run (e.g. a
    /// `[[output.combination]]` of the inlet flux and the leaflet's sweep).
    pub flux: String,
    /// A quantity positive while the valve is closed, e.g. `NAME_contact_force` of its
    /// `[[solid.contact]]`: the leak volume and the closing and opening times need it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact_force: Option<String>,
    /// Quantities whose largest value in each cycle is reported (e.g. `max_speed`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub peak: Vec<String>,
    /// Quantities whose largest value over each cycle's forward flow (the steps of its
    /// forward mean) is reported, e.g. the speed in the root: the peak systolic jet, not the
    /// leaflets' sweep as they close.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub forward_peak: Vec<String>,
    /// Quantities whose mean over each cycle's forward flow (`flux > 0`) is reported (e.g. the
    /// transvalvular pressure difference: the mean systolic gradient).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub forward_mean: Vec<String>,
}

/// The last period of a quantity of `history.csv` ([`crate::post::oscillation`]): its mean
/// `(max + min) / 2`, amplitude `(max - min) / 2` and frequency, written to `summary.json` as
/// `QUANTITY_mean`, `QUANTITY_amplitude` and `QUANTITY_frequency`.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct OscillationSpec {
    /// A quantity of the run (a probe, boundary integral, domain quantity, combination or
    /// built-in quantity).
    pub quantity: String,
    /// Only the steps from this time on (when the motion has become periodic); default 0.
    #[serde(default)]
    pub from: f64,
}

/// A quantity of the fluid domain, or of the part of it in a slab.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DomainQuantitySpec {
    pub name: String,
    pub kind: DomainQuantityKind,
    /// Only the fluid between two planes normal to an axis (default: all of it), e.g. a valve's
    /// root downstream of the annulus and short of the outlet, for the jet's speed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slab: Option<SlabSpec>,
}

/// The slab `from <= x_axis <= to` between two planes normal to a coordinate axis.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SlabSpec {
    pub axis: Axis,
    pub from: f64,
    /// `> from`.
    pub to: f64,
}

impl SlabSpec {
    /// Whether the point `x` lies in the slab (its faces included).
    pub fn contains<const D: usize>(&self, x: &[f64; D]) -> bool {
        x.get(self.axis.index()).is_some_and(|&v| self.from <= v && v <= self.to)
    }
}

/// Kinds of domain quantity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum DomainQuantityKind {
    /// `max |u|` over the vertices, edge midpoints and centroids of the fluid cells (the
    /// points where P2+ is interpolatory plus its bubble point; with a `slab`, those in it).
    MaxSpeed,
}

/// The plane through a 3D model that its `speed.png` shows, normal to a coordinate axis. Without
/// `[output.slice]` the normal is the axis along which the fluid mesh is thinnest (of equal ones
/// the last) and the plane goes through the middle of the solid (an FSI run) or of the fluid mesh.
#[derive(Clone, Copy, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SliceSpec {
    /// The axis normal to the plane.
    pub normal: Axis,
    /// Where the plane cuts that axis; default the middle of the solid or of the fluid mesh.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub at: Option<f64>,
}

/// A coordinate axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Axis {
    X = 0,
    Y = 1,
    Z = 2,
}

impl Axis {
    /// The coordinate's index: 0, 1 or 2.
    pub fn index(self) -> usize {
        self as usize
    }
}

/// A profile along a boundary: one row `s,x,y[,z],value` per facet quadrature point.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ProfileSpec {
    pub name: String,
    pub boundary: String,
    pub kind: ProfileKind,
}

/// Kinds of profile.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ProfileKind {
    /// Tangential part of the viscous traction `eta (grad u + grad u^T) n` of the fluid on the
    /// wall (`n` out of the fluid). 2D: its component along the direction of increasing `s`;
    /// 3D: its magnitude.
    WallShearStress,
    /// The pressure (from the cell on the boundary's side).
    Pressure,
}

/// `name = sum_k coefficient_k * quantity_k`, e.g. a pressure difference of two probes.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CombinationSpec {
    pub name: String,
    /// `[[quantity, coefficient], ...]`
    pub terms: Vec<(String, f64)>,
}

/// A point probe.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeSpec {
    pub name: String,
    pub field: ProbeField,
    /// Velocity or displacement component, `< dimension`.
    #[serde(default)]
    pub component: usize,
    /// One finite coordinate per dimension, inside the fluid mesh (velocity and pressure).
    pub point: Vec<f64>,
}

/// Fields a probe can read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ProbeField {
    Velocity,
    Pressure,
    /// Solid-only runs: the displacement at a node of the solid mesh (reference position).
    Displacement,
}

/// A boundary integral quantity.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BoundaryIntegralSpec {
    pub name: String,
    pub boundary: String,
    pub kind: BoundaryIntegralKind,
    /// For `force`: the component (0-based).
    #[serde(default)]
    pub component: usize,
    /// Factor the integral is multiplied by (e.g. `2 / (rho U^2 D)` for a drag coefficient).
    #[serde(default = "one")]
    pub scale: f64,
}

/// Kinds of boundary integral.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum BoundaryIntegralKind {
    /// Volume flux `int u . n ds` (weighted by `2 pi r` when axisymmetric).
    Flux,
    /// `int p ds / int ds`.
    MeanPressure,
    /// Component `component` of the force of the fluid on the boundary, `-int sigma n ds` (`n`
    /// out of the fluid), computed by the consistent residual (volume-integral) method: the
    /// residual of the momentum equations tested with a function equal to `e_component` on the
    /// boundary and zero on the other Dirichlet boundaries. Axisymmetric: the axial force
    /// `2 pi int ... r ds`.
    Force,
    /// The normal pressure that the boundary's `traction` or `pressure` condition applies,
    /// `-int t . n w ds / int w ds` (`t` the prescribed traction, `n` out of the fluid, `w = r`
    /// axisymmetric, else 1): the value itself for a `pressure` boundary. 0 on a boundary
    /// without such a condition.
    AppliedTraction,
}

/// The kinds of run ([`Case::kind`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RunKind {
    /// A fluid, with a fixed solid if any: steady or time-dependent flow.
    Flow,
    /// A solid alone, quasi-static (load stepping).
    Solid,
    /// A fluid and a moving solid coupled by the Lagrange multiplier.
    Fsi,
}

impl Case {
    /// Parses a case from TOML text; `file` names the source in error messages.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Case, CaseError> {
        toml::from_str::<Case>(text).map_err(|e| CaseError::Parse { file: file.to_string(), message: describe_toml_error(&e, text) })
    }

    /// Reads and parses a case file.
    pub fn read(path: &std::path::Path) -> Result<Case, CaseError> {
        let file = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|source| CaseError::Io { file: file.clone(), source })?;
        let text = String::from_utf8(bytes).map_err(|e| {
            let valid = &e.as_bytes()[..e.utf8_error().valid_up_to()];
            let line = valid.iter().filter(|&&b| b == b'\n').count() + 1;
            let start = valid.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
            let col = String::from_utf8_lossy(&valid[start..]).chars().count() + 1;
            let message = format!("line {line}, column {col}: not UTF-8 text (a case file is TOML, in UTF-8)");
            CaseError::Parse { file: file.clone(), message }
        })?;
        Self::from_toml_str(&text, &file)
    }

    /// The case as TOML (written next to the results).
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_else(|e| format!("# case could not be serialised: {e}\n"))
    }

    /// The kind of run the case describes: a solid alone (no fluid `[mesh]`), FSI (a fluid and a
    /// solid with a material `model`), or flow (a fluid, with a fixed solid if any).
    pub fn kind(&self) -> RunKind {
        match (&self.mesh, self.solid.first()) {
            (None, _) => RunKind::Solid,
            (Some(_), Some(s)) if s.model != SolidModel::Fixed => RunKind::Fsi,
            _ => RunKind::Flow,
        }
    }

    /// The quantities every run of this kind writes besides the case's own (they may appear in
    /// `[[output.combination]]`): in FSI runs `coupling_force_x`, `_y` (`_z`), the force of the
    /// fluid on the solid, and `coupling_facets`; with contacts also `closed_gap_cells`, the
    /// fluid cells cut off where the solid has closed on a plane or on another body, and
    /// `film_force_x`, `_y` (`_z`), the part of the force the films in those gaps carry; with
    /// `[output.open_area]` also `open_area` (in this order).
    pub fn builtin_quantities(&self) -> Vec<String> {
        if self.kind() != RunKind::Fsi {
            return Vec::new();
        }
        let mut names: Vec<String> = ["x", "y", "z"][..self.dim()].iter().map(|c| format!("coupling_force_{c}")).collect();
        names.push("coupling_facets".into());
        if self.solid.iter().any(|s| !s.contact.is_empty()) {
            names.push("closed_gap_cells".into());
            names.extend(["x", "y", "z"][..self.dim()].iter().map(|c| format!("film_force_{c}")));
        }
        if self.output.open_area.is_some() {
            names.push("open_area".into());
        }
        names
    }

    /// All the quantities a run writes besides the case's own: the
    /// [`Case::builtin_quantities`], for each `[[solid.contact]]` boundary `B`
    /// `B_contact_force`, `B_contact_pressure_max` and `B_gap_min`, and for each Windkessel
    /// outlet `O` `O_flux`, `O_pressure` and `O_capacitor_pressure`.
    pub fn run_quantities(&self) -> Vec<String> {
        let mut names = self.builtin_quantities();
        let contacts = self.solid.iter().enumerate().flat_map(|(k, s)| s.contact.iter().map(move |c| self.solid_boundary(k, &c.boundary)));
        names.extend(contacts.flat_map(|b| CONTACT_QUANTITIES.map(|q| format!("{b}_{q}"))));
        let outlets = self.boundary.iter().filter(|b| b.kind == BoundaryType::Windkessel);
        names.extend(outlets.flat_map(|b| WINDKESSEL_QUANTITIES.map(|q| format!("{}_{q}", b.name))));
        names
    }

    /// What becomes of the fluid the solid covers (`kept` without a solid).
    pub fn covered_fluid(&self) -> crate::adapt::CoveredFluid {
        self.solid.first().map(|s| s.covered_fluid).unwrap_or_default()
    }

    /// The first (or only) solid: with several, the options of the whole solid are its (`model`
    /// as fixed or not, `multiplier`, `covered_fluid`, `film_pressure`, `film_squeeze`, `eps_hat`, `min_move_quality`, `boundary_cuts`,
    /// `min_cut_quality`, `loading`; validation holds them
    /// equal).
    pub fn first_solid(&self) -> Option<&SolidSpec> {
        self.solid.first()
    }

    /// The name, in the joined solid mesh, of the boundary `local` of solid `k`: `local` itself
    /// with one solid, `NAME/local` with several (`NAME` solid `k`'s name). A name that already
    /// starts with another solid's `NAME/` is kept: a contact `against` another solid.
    pub fn solid_boundary(&self, k: usize, local: &str) -> String {
        if self.solid.len() < 2 {
            return local.to_string();
        }
        let named = |s: &SolidSpec| s.name.as_deref().is_some_and(|n| local.strip_prefix(n).is_some_and(|rest| rest.starts_with('/')));
        if self.solid.iter().any(named) {
            return local.to_string();
        }
        format!("{}/{local}", self.solid[k].name.as_deref().unwrap_or_default())
    }

    /// The name of gamma_s in the joined solid mesh: the union of every solid's `surface`
    /// ([`Case::solid_surfaces`], joined by `+`); `None` if a solid has none.
    pub fn solid_surface(&self) -> Option<String> {
        self.solid_surfaces().map(|n| n.join("+"))
    }

    /// Every solid's `surface`, by its name in the joined solid mesh; `None` without solids or if
    /// one has none.
    pub fn solid_surfaces(&self) -> Option<Vec<String>> {
        let names: Option<Vec<String>> =
            self.solid.iter().enumerate().map(|(k, s)| s.surface.as_ref().map(|b| self.solid_boundary(k, &b.joined()))).collect();
        names.filter(|n| !n.is_empty())
    }

    /// Spatial dimension implied by the formulation.
    pub fn dim(&self) -> usize {
        if self.physics.formulation == Formulation::ThreeD {
            3
        } else {
            2
        }
    }
}

/// The quantities each `[[solid.contact]]` boundary `B` writes, `B_SUFFIX`, in this order: the
/// contact force, the largest contact pressure, the smallest gap.
pub const CONTACT_QUANTITIES: [&str; 3] = ["contact_force", "contact_pressure_max", "gap_min"];

/// The quantities each Windkessel outlet `O` writes, `O_SUFFIX`, in this order: its flux `Q`, the
/// outlet pressure `R_p Q + P_c` and the capacitor pressure `P_c`.
pub const WINDKESSEL_QUANTITIES: [&str; 3] = ["flux", "pressure", "capacitor_pressure"];

/// At most this many halvings of a failing step (`time.max_cuts`).
pub const MAX_CUTS: usize = 20;

/// At most this many time steps (`time.end / time.dt`) or load steps.
pub const MAX_STEPS: usize = 100_000_000;

/// At most this many cells in a generated mesh.
pub const MAX_GENERATED_CELLS: usize = 100_000_000;

/// A TOML error with line and column, and for an unknown key the nearest valid one. The
/// messages of `toml` and `serde` are reworded where they speak Rust (`usize`, `f64`, untagged
/// enums) rather than TOML, and completed with the key for duplicate keys, the table for missing
/// keys.
fn describe_toml_error(e: &toml::de::Error, text: &str) -> String {
    let mut msg = reword(e.message());
    if let Some(span) = e.span() {
        let (start, end) = (char_floor(text, span.start), char_floor(text, span.end.max(span.start)));
        let before = &text[..start];
        let found = &text[start..end];
        let line = before.matches('\n').count() + 1;
        let line_start = before.rfind('\n').map(|i| i + 1).unwrap_or(0);
        let col = before[line_start..].chars().count() + 1;
        let line_text = text[line_start..].lines().next().unwrap_or("");
        if msg == "duplicate key" && !found.trim().is_empty() {
            msg = format!("duplicate key `{}`", found.trim().trim_matches('"'));
        } else if msg.starts_with("missing field") {
            let header = line_text.trim();
            if start == 0 && !header.starts_with('[') {
                msg.push_str(" (required at the top level of the case)");
            } else if header.starts_with('[') {
                msg.push_str(&format!(" (required in {header})"));
            }
        } else if let Some((key, value)) = line_text.split_once('=') {
            if value.split('#').next().unwrap_or("").trim().is_empty() && !key.contains('"') && !key.contains('[') {
                msg = format!("`{}` has no value after `=`", key.trim());
            }
        }
        msg = format!("line {line}, column {col}: {msg}");
        if let Some(hint) = nearest_key_hint(e.message(), found) {
            msg.push_str(&format!(" (did you mean `{hint}`?)"));
        }
    }
    msg
}

/// The largest char boundary of `text` at or below `i`.
fn char_floor(text: &str, i: usize) -> usize {
    let mut i = i.min(text.len());
    while !text.is_char_boundary(i) {
        i -= 1;
    }
    i
}

/// Rewords the parts of a `toml`/`serde` message that name Rust types.
fn reword(message: &str) -> String {
    let mut m = message.trim_end().to_string();
    for (from, to) in [
        ("data did not match any variant of untagged enum Scalar", "expected a number or an expression (a string)"),
        ("expected usize", "expected a whole number >= 0"),
        ("expected u32", "expected a whole number >= 0"),
        ("expected f64", "expected a number"),
        ("expected a sequence", "expected an array"),
        ("invalid type: sequence", "invalid type: array"),
        ("invalid type: map", "invalid type: table"),
        ("expected a borrowed string", "expected a string"),
        (", expected nothing", ""),
    ] {
        m = m.replace(from, to);
    }
    m
}

/// For "unknown field `foo`, expected one of `a`, `b`": the expected key closest to `foo`.
fn nearest_key_hint(message: &str, found: &str) -> Option<String> {
    let list = message.split("expected").nth(1)?;
    let candidates: Vec<&str> = list.split('`').skip(1).step_by(2).collect();
    let found = found.trim().trim_matches('"');
    nearest_name(candidates.into_iter(), found)
}

/// The candidate closest to `found` (edit distance at most 3, and less than the length of
/// `found`), e.g. to suggest a boundary name.
pub(crate) fn nearest_name<'a>(candidates: impl Iterator<Item = &'a str>, found: &str) -> Option<String> {
    if found.chars().count() > 64 {
        return None;
    }
    let limit = 3.min(found.chars().count().saturating_sub(1));
    candidates
        .filter(|c| c.chars().count() <= 64)
        .map(|c| (edit_distance(c, found), c))
        .filter(|(d, _)| *d <= limit)
        .min()
        .map(|(_, c)| c.to_string())
}

/// Edit distance with transpositions (optimal string alignment; small strings only): `titel`
/// is 1 from `title`.
fn edit_distance(a: &str, b: &str) -> usize {
    let (a, b): (Vec<char>, Vec<char>) = (a.chars().collect(), b.chars().collect());
    let mut d = vec![vec![0usize; b.len() + 1]; a.len() + 1];
    for (i, row) in d.iter_mut().enumerate() {
        row[0] = i;
    }
    for j in 0..=b.len() {
        d[0][j] = j;
    }
    for i in 1..=a.len() {
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            let mut v = (d[i - 1][j - 1] + cost).min(d[i - 1][j] + 1).min(d[i][j - 1] + 1);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                v = v.min(d[i - 2][j - 2] + 1);
            }
            d[i][j] = v;
        }
    }
    d[a.len()][b.len()]
}

/// The name of a unit enum variant as the case file spells it, quoted (`"3d"`).
fn spelled<T: Serialize + std::fmt::Debug>(v: &T) -> String {
    format!("\"{}\"", name_of(v))
}

/// The name of a unit enum variant as the case file spells it (`3d`, `neo-hookean`).
pub(crate) fn name_of<T: Serialize + std::fmt::Debug>(v: &T) -> String {
    match serde_json::to_value(v) {
        Ok(serde_json::Value::String(s)) => s,
        _ => format!("{v:?}"),
    }
}

/// A compiled scalar expression of `x, y, z, r, t` (`r` is `y`, the radius of axisymmetric runs).
#[derive(Clone)]
pub struct Expr {
    kind: ExprKind,
}

impl std::fmt::Debug for Expr {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.kind {
            ExprKind::Constant(v) => write!(f, "Expr({v})"),
            ExprKind::Compiled { .. } => write!(f, "Expr(<compiled>)"),
        }
    }
}

#[derive(Clone)]
enum ExprKind {
    Constant(f64),
    Compiled { expr: Arc<exmex::FlatEx<f64>>, slots: Vec<usize> },
}

const VARIABLES: [&str; 5] = ["x", "y", "z", "r", "t"];

/// The functions of exmex's default `f64` operators (besides the infix `min`, `max`, `atan2`).
const FUNCTIONS: [&str; 26] = [
    "abs", "signum", "sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "asinh", "acosh", "atanh", "floor", "round", "ceil",
    "trunc", "fract", "exp", "sqrt", "cbrt", "ln", "log", "log2", "log10",
];

/// The first name followed by `(` that is not a known function.
fn unknown_function(text: &str) -> Option<String> {
    let chars: Vec<char> = text.chars().collect();
    let mut i = 0;
    while i < chars.len() {
        if chars[i].is_alphabetic() || chars[i] == '_' {
            let s = i;
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            let name: String = chars[s..i].iter().collect();
            let mut j = i;
            while j < chars.len() && chars[j].is_whitespace() {
                j += 1;
            }
            let known = FUNCTIONS.contains(&name.as_str()) || ["min", "max", "atan2"].contains(&name.as_str());
            if chars.get(j) == Some(&'(') && !known {
                return Some(name);
            }
        } else {
            i += 1;
        }
    }
    None
}

impl Expr {
    /// Compiles a number or an expression; unknown variables are an error.
    pub fn compile(s: &Scalar) -> Result<Expr, String> {
        use exmex::Express;
        match s {
            Scalar::Number(v) => Ok(Expr { kind: ExprKind::Constant(*v) }),
            Scalar::Expression(text) => {
                let expr = exmex::parse::<f64>(text).map_err(|e| match unknown_function(text) {
                    Some(f) => format!("cannot parse expression \"{text}\": unknown function `{f}` (known: {})", FUNCTIONS.join(", ")),
                    None => format!("cannot parse expression \"{text}\": {e}"),
                })?;
                let mut slots = Vec::new();
                for name in expr.var_names() {
                    let k = VARIABLES
                        .iter()
                        .position(|v| v == name)
                        .ok_or_else(|| format!("expression \"{text}\": unknown variable `{name}` (use x, y, z, r, t)"))?;
                    slots.push(k);
                }
                Ok(Expr { kind: ExprKind::Compiled { expr: Arc::new(expr), slots } })
            }
        }
    }

    /// Value at point `x` (padded with zeros to 3 components) and time `t`; a failed evaluation
    /// gives NaN, which the solver reports as a non-finite residual.
    pub fn eval(&self, x: &[f64], t: f64) -> f64 {
        use exmex::Express;
        match &self.kind {
            ExprKind::Constant(v) => *v,
            ExprKind::Compiled { expr, slots } => {
                let all = [
                    x.first().copied().unwrap_or(0.0),
                    x.get(1).copied().unwrap_or(0.0),
                    x.get(2).copied().unwrap_or(0.0),
                    x.get(1).copied().unwrap_or(0.0),
                    t,
                ];
                let mut vals = [0.0; 5];
                for (i, &k) in slots.iter().enumerate() {
                    vals[i] = all[k];
                }
                expr.eval(&vals[..slots.len()]).unwrap_or(f64::NAN)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One `[solid]` table is written back as one (a case's `case.toml`, and its hash, do not
    /// change), several `[[solid]]` tables as several; both read back the same; and the boundary
    /// names seen from outside a table are qualified by the solid's name only with several.
    #[test]
    fn one_solid_or_several_round_trip() {
        let table = |header: &str, name: &str| {
            format!("{header}\nname = \"{name}\"\nmesh = {{ kind = \"rectangle\", x = [0.0, 1.0], y = [0.0, 1.0], n = [1, 1] }}\nsurface = \"top\"\nmodel = \"neo-hookean\"\nshear_modulus = 1.0\n\n[[solid.boundary]]\nname = \"left\"\ntype = \"displacement\"\nvalue = [0.0, 0.0]\n")
        };
        let head = "title = \"t\"\n[physics]\nformulation = \"plane\"\n";
        let one = Case::from_toml_str(&format!("{head}{}", table("[solid]", "a")), "one.toml").unwrap();
        assert_eq!(one.solid.len(), 1);
        let text = one.to_toml();
        assert!(text.contains("\n[solid]\n") && !text.contains("[[solid]]"), "{text}");
        assert_eq!((one.solid_boundary(0, "left"), one.solid_surface()), ("left".into(), Some("top".into())));
        let two = Case::from_toml_str(&format!("{head}{}{}", table("[[solid]]", "a"), table("[[solid]]", "b")), "two.toml").unwrap();
        assert_eq!(two.solid.iter().map(|s| s.name.as_deref().unwrap()).collect::<Vec<_>>(), ["a", "b"]);
        assert_eq!(two.solid[1].boundary[0].name, "left", "a [[solid.boundary]] belongs to the [[solid]] before it");
        let text = two.to_toml();
        assert_eq!(text.matches("[[solid]]").count(), 2, "{text}");
        assert_eq!(Case::from_toml_str(&text, "two.toml").unwrap().to_toml(), text);
        assert_eq!(two.solid_boundary(1, "left"), "b/left");
        assert_eq!(two.solid_boundary(1, "a/right"), "a/right", "another solid's boundary is named in full");
        assert_eq!(two.solid_surface(), Some("a/top+b/top".into()));
        // The adaptation's newer options are written only where given: a case (a checkpoint's)
        // written before them reads back as the same text.
        assert!(!text.contains("min_move_quality") && !text.contains("boundary_cuts"), "{text}");
        let given = format!("{head}{}", table("[solid]", "a").replace("surface", "min_move_quality = 0.001\nboundary_cuts = \"touch\"\nsurface"));
        let text = Case::from_toml_str(&given, "given.toml").unwrap().to_toml();
        assert!(text.contains("min_move_quality = 0.001") && text.contains("boundary_cuts = \"touch\""), "{text}");
    }

    /// Every pair of elastic constants of one material (Turek-Hron's bar: G = 0.5e6, nu = 0.4,
    /// so E = 1.4e6, lambda = 2e6, K = 2e6 + 1e6/3) gives its G and K.
    #[test]
    fn any_two_elastic_constants_give_the_shear_and_bulk_moduli() {
        let (g, k, l, e, nu) = (0.5e6, 2.0e6 + 1.0e6 / 3.0, 2.0e6, 1.4e6, 0.4);
        let all = [Some(g), Some(k), Some(l), Some(e), Some(nu)];
        let solid = |c: [Option<f64>; 5]| {
            let text = "mesh = { kind = \"rectangle\", x = [0.0, 1.0], y = [0.0, 1.0], n = [1, 1] }\nmodel = \"saint-venant-kirchhoff\"\n";
            let mut spec: SolidSpec = toml::from_str(text).unwrap();
            [spec.shear_modulus, spec.bulk_modulus, spec.lame_lambda, spec.youngs_modulus, spec.poissons_ratio] = c;
            spec
        };
        for a in 0..5 {
            for b in a + 1..5 {
                let mut c = [None; 5];
                (c[a], c[b]) = (all[a], all[b]);
                let m = solid(c).moduli().unwrap_or_else(|err| panic!("pair {a}, {b}: {err}"));
                assert!((m.shear - g).abs() < 1e-9 * g && (m.bulk.unwrap() - k).abs() < 1e-9 * k, "pair {a}, {b}: {m:?}");
            }
        }
        assert_eq!(solid([Some(g), None, None, None, None]).moduli().unwrap(), Moduli { shear: g, bulk: None });
        assert!(solid([None; 5]).moduli().unwrap_err().contains("got none"));
        assert!(solid([Some(g), Some(k), Some(l), None, None]).moduli().is_err());
        assert!(solid([None, None, None, Some(e), Some(0.5)]).moduli().is_err());
        // Singular pairs: E = 3 G (K infinite), lambda with nu = 0.
        assert!(solid([Some(g), None, None, Some(3.0 * g), None]).moduli().unwrap_err().contains("finite"));
        assert!(solid([None, None, Some(l), None, Some(0.0)]).moduli().unwrap_err().contains("do not determine"));
    }

    const GOOD: &str = r#"
title = "t"
[mesh]
kind = "rectangle"
x = [0.0, 1.0]
y = [0.0, 1.0]
n = [2, 2]
[physics]
formulation = "plane"
[fluid]
density = 1.0
viscosity = 1.0
[[boundary]]
name = "left"
type = "velocity"
value = ["4*y*(1-y)", 0]
"#;

    #[test]
    fn parses_and_validates_a_good_case() {
        let c = Case::from_toml_str(GOOD, "good.toml").unwrap();
        c.validate("good.toml").unwrap();
        let e = Expr::compile(&c.boundary[0].value[0]).unwrap();
        assert!((e.eval(&[0.0, 0.5], 0.0) - 1.0).abs() < 1e-15);
        // Round trip through the written form.
        let again = Case::from_toml_str(&c.to_toml(), "again.toml").unwrap();
        assert_eq!(again.boundary.len(), 1);
    }

    /// The AL placements: unset, the coupling multiplier and the boundary groups go to the Schur
    /// block in 3D only and the solid pressure stays primal; set, they are taken as written, and
    /// unset keys are not written back.
    #[test]
    fn al_placements_default_by_dimension() {
        let c = Case::from_toml_str(GOOD, "good.toml").unwrap();
        let (plane, three) = (c.solver.linear.al_options(true, Formulation::Plane), c.solver.linear.al_options(true, Formulation::ThreeD));
        assert_eq!((plane.boundary, plane.coupling, plane.solid_pressure), (Placement::Primal, Placement::Primal, Placement::Primal));
        assert_eq!((three.boundary, three.coupling, three.solid_pressure), (Placement::Schur, Placement::Schur, Placement::Primal));
        assert!(!c.to_toml().contains("solid_pressure") && !c.to_toml().contains("coupling_multipliers"), "{}", c.to_toml());
        let set = format!("{GOOD}\n[solver.linear]\nsolid_pressure = \"schur\"\ncoupling_multipliers = \"primal\"\n");
        let c = Case::from_toml_str(&set, "set.toml").unwrap();
        let three = c.solver.linear.al_options(true, Formulation::ThreeD);
        assert_eq!((three.boundary, three.coupling, three.solid_pressure), (Placement::Schur, Placement::Primal, Placement::Schur));
    }

    #[test]
    fn unknown_key_names_line_and_suggests() {
        let bad = GOOD.replace("viscosity = 1.0", "viscosty = 1.0");
        let e = Case::from_toml_str(&bad, "bad.toml").unwrap_err().to_string();
        assert!(e.contains("bad.toml"), "{e}");
        assert!(e.contains("line 12, column 1"), "{e}");
        assert!(e.contains("did you mean `viscosity`"), "{e}");
    }

    #[test]
    fn ranges_and_counts_are_checked() {
        let bad = GOOD.replace("density = 1.0", "density = -1.0").replace("value = [\"4*y*(1-y)\", 0]", "value = [1]");
        let c = Case::from_toml_str(&bad, "b.toml").unwrap();
        let e = c.validate("b.toml").unwrap_err().to_string();
        assert!(e.contains("fluid.density must be a positive number"), "{e}");
        assert!(e.contains("needs 2 entries, got 1"), "{e}");
    }

    #[test]
    fn suggestions_count_transpositions() {
        assert_eq!(edit_distance("titel", "title"), 1);
        assert_eq!(edit_distance("viscosty", "viscosity"), 1);
        assert_eq!(nearest_name(["time", "title"].into_iter(), "titel").as_deref(), Some("title"));
        assert_eq!(nearest_name(["left", "top"].into_iter(), "x"), None);
    }

    #[test]
    fn toml_messages_speak_toml() {
        let e = Case::from_toml_str(&GOOD.replace("n = [2, 2]", "n = [2, -2]"), "b.toml").unwrap_err().to_string();
        // Inside the internally tagged [mesh] table the span is the table header.
        assert!(e.contains("line 3, column 1") && e.contains("integer `-2`, expected a whole number >= 0"), "{e}");
        let e = Case::from_toml_str(&GOOD.replace("density = 1.0", "density ="), "b.toml").unwrap_err().to_string();
        assert!(e.contains("`density` has no value after `=`"), "{e}");
        let e = Case::from_toml_str(&GOOD.replace("[physics]", "[physics]\nformulation = \"3d\""), "b.toml").unwrap_err().to_string();
        assert!(e.contains("duplicate key `formulation`"), "{e}");
    }

    #[test]
    fn expressions_reject_unknown_variables() {
        assert!(Expr::compile(&Scalar::Expression("sin(q)".into())).unwrap_err().contains("unknown variable `q`"));
        let e = Expr::compile(&Scalar::Expression("r^2 + t*PI".into())).unwrap();
        assert!((e.eval(&[0.0, 2.0], 1.0) - (4.0 + std::f64::consts::PI)).abs() < 1e-14);
    }
}

/// A [`TimeFunction`] ready to evaluate (tables loaded).
#[derive(Clone, Debug)]
pub enum TimeFn {
    Constant,
    Ramp(f64),
    Sine(f64, f64),
    QuarterSineHold(f64),
    /// The rows and the period (if the table repeats).
    Table(Arc<Vec<(f64, f64)>>, Option<f64>),
}

impl TimeFn {
    /// Loads a time function (reads a table file relative to `case_dir`).
    pub fn load(f: &TimeFunction, case_dir: &std::path::Path) -> Result<TimeFn, CaseError> {
        Ok(match f {
            TimeFunction::Constant => TimeFn::Constant,
            TimeFunction::Ramp { duration } => TimeFn::Ramp(*duration),
            TimeFunction::Sine { period, phase } => TimeFn::Sine(*period, *phase),
            TimeFunction::QuarterSineHold { rise } => TimeFn::QuarterSineHold(*rise),
            TimeFunction::Table { file, period } => {
                let path = case_dir.join(file);
                let name = path.display().to_string();
                let text = std::fs::read_to_string(&path).map_err(|source| CaseError::Io { file: name.clone(), source })?;
                TimeFn::Table(Arc::new(parse_table(&text, &name)?), *period)
            }
        })
    }

    /// Value at time `t`.
    pub fn eval(&self, t: f64) -> f64 {
        use std::f64::consts::PI;
        match self {
            TimeFn::Constant => 1.0,
            TimeFn::Ramp(d) => (t / d).clamp(0.0, 1.0),
            TimeFn::Sine(p, phase) => (2.0 * PI * t / p + phase).sin(),
            TimeFn::QuarterSineHold(r) => {
                if t < *r {
                    (0.5 * PI * t / r).sin()
                } else {
                    1.0
                }
            }
            TimeFn::Table(rows, None) => interpolate(rows, t),
            TimeFn::Table(rows, Some(p)) => interpolate(rows, t - p * (t / p).floor()),
        }
    }
}

/// Rows `t,value` of a CSV table, strictly increasing in `t`.
fn parse_table(text: &str, file: &str) -> Result<Vec<(f64, f64)>, CaseError> {
    let mut rows: Vec<(f64, f64)> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let cols: Vec<&str> = line.split(',').map(str::trim).collect();
        let parsed = (cols.len() == 2).then(|| (cols[0].parse::<f64>(), cols[1].parse::<f64>()));
        match parsed {
            Some((Ok(t), Ok(v))) => {
                if !(t.is_finite() && v.is_finite()) {
                    let message = format!("line {}: `{line}`: t and value must be finite numbers", i + 1);
                    return Err(CaseError::Invalid { file: file.into(), message });
                }
                if rows.last().is_some_and(|&(tp, _)| t <= tp) {
                    return Err(CaseError::Invalid { file: file.into(), message: format!("line {}: times must increase", i + 1) });
                }
                rows.push((t, v));
            }
            _ if rows.is_empty() && i == 0 => {} // header
            _ => return Err(CaseError::Invalid { file: file.into(), message: format!("line {}: expected `t,value`, got `{line}`", i + 1) }),
        }
    }
    if rows.is_empty() {
        return Err(CaseError::Invalid { file: file.into(), message: "the table has no rows".into() });
    }
    Ok(rows)
}

fn interpolate(rows: &[(f64, f64)], t: f64) -> f64 {
    let k = rows.partition_point(|&(tk, _)| tk <= t);
    if k == 0 {
        return rows[0].1;
    }
    if k == rows.len() {
        return rows[k - 1].1;
    }
    let ((t0, v0), (t1, v1)) = (rows[k - 1], rows[k]);
    v0 + (v1 - v0) * (t - t0) / (t1 - t0)
}

#[cfg(test)]
mod time_function_tests {
    use super::*;

    #[test]
    fn time_functions_evaluate() {
        assert_eq!(TimeFn::Ramp(2.0).eval(1.0), 0.5);
        assert_eq!(TimeFn::Ramp(2.0).eval(3.0), 1.0);
        assert!((TimeFn::QuarterSineHold(2.0).eval(1.0) - (std::f64::consts::PI / 4.0).sin()).abs() < 1e-15);
        assert_eq!(TimeFn::QuarterSineHold(2.0).eval(5.0), 1.0);
        assert!((TimeFn::Sine(4.0, 0.0).eval(1.0) - 1.0).abs() < 1e-15);
        let rows = parse_table("t,value\n0,0\n1,2\n3,2\n", "x.csv").unwrap();
        let f = TimeFn::Table(Arc::new(rows.clone()), None);
        assert_eq!(f.eval(0.5), 1.0);
        assert_eq!(f.eval(10.0), 2.0);
        assert_eq!(f.eval(-1.0), 0.0);
        // Repeated with period 4: t = 8.5 and 4.5 read the table at 0.5.
        let periodic = TimeFn::Table(Arc::new(rows), Some(4.0));
        assert_eq!(periodic.eval(8.5), 1.0);
        assert_eq!(periodic.eval(4.5), 1.0);
        assert_eq!(periodic.eval(3.5), 2.0);
        assert!(parse_table("0,1\n0,2\n", "x.csv").unwrap_err().to_string().contains("times must increase"));
        assert!(parse_table("0,1\nfoo\n", "x.csv").unwrap_err().to_string().contains("line 2"));
    }
}
