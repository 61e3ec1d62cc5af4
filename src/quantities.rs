//! Derived quantities of a flow solution: point probes and boundary integrals.
//!
//! - probe: `u_a(x_p)` or `p(x_p)`, by evaluating the P2+ (or P1disc) basis of the cell that
//!   contains `x_p` at its reference coordinates;
//! - flux: `Q = int_Gamma u . n ds` (axisymmetric: `2 pi int u . n r ds`, the physical volume
//!   flow);
//! - mean pressure: `int_Gamma p w ds / int_Gamma w ds` (`w = r` axisymmetric, else 1).

use crate::case::{BoundaryIntegralKind, BoundaryIntegralSpec, ProbeField, ProbeSpec};
use crate::flow::{FlowDiscretization, FlowError};
use crate::physics::fluid::Formulation;
use fdfsi_fem::element::MAX_DOFS;
use fdfsi_fem::locate::locate_point;
use fdfsi_fem::values::p1disc_basis;

/// Evaluates a probe; `None` when the point lies outside the mesh.
pub fn probe<const D: usize>(disc: &FlowDiscretization<D>, x: &[f64], spec: &ProbeSpec) -> Option<f64> {
    let xp: [f64; D] = std::array::from_fn(|d| spec.point.get(d).copied().unwrap_or(0.0));
    let (c, xi) = locate_point(&disc.mesh, &xp)?;
    match spec.field {
        ProbeField::Velocity => {
            let vf = &disc.layout.fields[0];
            let n = disc.velocity_element.num_dofs();
            let mut vals = [0.0; MAX_DOFS];
            let mut grads = [[0.0; D]; MAX_DOFS];
            disc.velocity_element.eval_into(&xi, &mut vals[..n], &mut grads[..n]);
            Some(vf.nodes.cell(c).iter().zip(&vals[..n]).map(|(&node, v)| v * x[vf.dof(node, spec.component)]).sum())
        }
        ProbeField::Pressure => {
            let pf = &disc.layout.fields[1];
            let centroid = cell_centroid(disc, c);
            let mut psi = [0.0; 4];
            p1disc_basis(&xp, &centroid, &mut psi);
            Some((0..=D).map(|k| x[pf.dof(c * (D + 1) + k, 0)] * psi[k]).sum())
        }
    }
}

/// Physical centroid of cell `c` (the image of the reference centroid).
fn cell_centroid<const D: usize>(disc: &FlowDiscretization<D>, c: usize) -> [f64; D] {
    let geo = &disc.geometry_element;
    let xi: [f64; D] = geo.cell().centroid();
    let tab = geo.tabulate(&[xi]);
    let mut out = [0.0; D];
    for (k, &node) in disc.mesh.cell(c).iter().enumerate() {
        for d in 0..D {
            out[d] += tab.values[k] * disc.mesh.points[node][d];
        }
    }
    out
}

/// Evaluates a boundary integral.
pub fn boundary_integral<const D: usize>(
    disc: &FlowDiscretization<D>,
    formulation: Formulation,
    x: &[f64],
    spec: &BoundaryIntegralSpec,
) -> Result<f64, FlowError> {
    let facets = disc.mesh.boundary_facets(&spec.boundary)?;
    let mut fv = disc.facet_values();
    let vf = &disc.layout.fields[0];
    let pf = &disc.layout.fields[1];
    let mut coords = Vec::new();
    let (mut num, mut den) = (0.0, 0.0);
    let mut psi = [0.0; 4];
    for bf in facets {
        disc.mesh.cell_coords_into(bf.cell, &mut coords);
        fv.reinit(&coords, bf.facet).map_err(|source| FlowError::Map { cell: bf.cell, source })?;
        let nodes = vf.nodes.cell(bf.cell);
        let centroid = cell_centroid(disc, bf.cell);
        for q in 0..fv.num_points() {
            let xq = fv.x[q];
            let w = fv.jxw[q] * formulation.weight(&xq);
            match spec.kind {
                BoundaryIntegralKind::Flux => {
                    let phi = fv.phi(q);
                    let mut un = 0.0;
                    for (i, &node) in nodes.iter().enumerate() {
                        for a in 0..D {
                            un += phi[i] * x[vf.dof(node, a)] * fv.normal[q][a];
                        }
                    }
                    num += w * un;
                }
                BoundaryIntegralKind::MeanPressure => {
                    p1disc_basis(&xq, &centroid, &mut psi);
                    let p: f64 = (0..=D).map(|k| x[pf.dof(bf.cell * (D + 1) + k, 0)] * psi[k]).sum();
                    num += w * p;
                    den += w;
                }
            }
        }
    }
    Ok(match spec.kind {
        BoundaryIntegralKind::Flux if formulation == Formulation::Axisymmetric => 2.0 * std::f64::consts::PI * num,
        BoundaryIntegralKind::Flux => num,
        BoundaryIntegralKind::MeanPressure => num / den,
    })
}
