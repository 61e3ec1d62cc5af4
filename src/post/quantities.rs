//! Derived quantities of a flow solution: point probes and boundary integrals.
//!
//! - probe: `u_a(x_p)` or `p(x_p)`, by evaluating the P2+ (or P1disc) basis of the cell that
//!   contains `x_p` at its reference coordinates; the pressure jumps between cells, so a pressure
//!   probe on a facet, edge or vertex is the mean of the values of all cells that contain it;
//! - flux: `Q = int_Gamma u . n ds` (axisymmetric: `2 pi int u . n r ds`, the physical volume
//!   flow);
//! - mean pressure: `int_Gamma p w ds / int_Gamma w ds` (`w = r` axisymmetric, else 1);
//! - applied traction: `-int_Gamma t . n w ds / int_Gamma w ds`, the normal pressure that a
//!   traction or pressure condition puts on the boundary;
//! - max speed: `max |u|` over the vertices, edge midpoints and centroids of the cells.

use crate::case::{
    BoundaryIntegralKind, BoundaryIntegralSpec, DomainQuantityKind, DomainQuantitySpec, ProbeField, ProbeSpec, SlabSpec, WINDKESSEL_QUANTITIES,
};
use crate::discretize::flow::{FlowDiscretization, FlowError, FlowProblem};
use fdfsi_fem::element::MAX_DOFS;
use fdfsi_fem::locate::{cells_containing, locate_point};
use fdfsi_fem::values::p1disc_basis;

/// Evaluates a probe of the fluid; `None` when the point lies outside the mesh (or the field is
/// not a fluid field).
pub fn probe<const D: usize>(disc: &FlowDiscretization<D>, x: &[f64], spec: &ProbeSpec) -> Option<f64> {
    let xp: [f64; D] = std::array::from_fn(|d| spec.point.get(d).copied().unwrap_or(0.0));
    match spec.field {
        ProbeField::Velocity => {
            let (c, xi) = locate_point(&disc.mesh, &xp)?;
            let vf = &disc.velocity_field();
            let n = disc.velocity_element.num_dofs();
            let mut vals = [0.0; MAX_DOFS];
            let mut grads = [[0.0; D]; MAX_DOFS];
            disc.velocity_element.eval_into(&xi, &mut vals[..n], &mut grads[..n]);
            Some(vf.nodes.cell(c).iter().zip(&vals[..n]).map(|(&node, v)| v * x[vf.dof(node, spec.component)]).sum())
        }
        ProbeField::Displacement => None,
        ProbeField::Pressure => {
            let pf = &disc.pressure_field();
            let cells = cells_containing(&disc.mesh, &xp);
            if cells.is_empty() {
                return None;
            }
            let mut psi = [0.0; 4];
            let sum: f64 = cells
                .iter()
                .map(|&(c, _)| {
                    p1disc_basis(&xp, &cell_centroid(disc, c), &mut psi);
                    (0..=D).map(|k| x[pf.dof(c * (D + 1) + k, 0)] * psi[k]).sum::<f64>()
                })
                .sum();
            Some(sum / cells.len() as f64)
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

/// Force of the fluid on boundary `boundary`, `F = -int sigma n ds`, by the consistent residual
/// method: with `R` the unconstrained residual of the momentum equations at the solution and
/// `v_a` the discrete function equal to `e_a` at the velocity nodes of the boundary and zero
/// elsewhere, `int (sigma n) . e_a ds = R(v_a)`. Exact for the discrete solution (no
/// differentiation of the velocity on the wall) and converges at the rate of the energy norm
/// squared. Axisymmetric: multiplied by `2 pi` (the weight `r` is in `R`).
/// For unsteady runs `state` gives the step's `inv_dt`, history `u*` and time (see
/// [`crate::time`]), so the inertia of the fluid next to the wall is included. With SUPG
/// (`[fluid] stabilization`) `R` holds its term `sum tau (u . grad v_a) . r` too, in the cells
/// at the wall: the force balancing the stabilised discrete equations (the term vanishes as the
/// strong residual `r` does).
pub fn boundary_force<const D: usize>(
    disc: &FlowDiscretization<D>,
    problem: &FlowProblem<D>,
    x: &[f64],
    state: &StepState<'_>,
    boundary: &str,
) -> Result<[f64; D], FlowError> {
    let n = disc.num_dofs();
    let mut step_problem = problem.clone();
    step_problem.params.inv_dt = state.inv_dt;
    let raw = disc.raw_residual(&step_problem, x, state.u_star.unwrap_or(x), state.time)?;
    let vf = &disc.velocity_field();
    let mut on_boundary = vec![false; vf.nodes.num_nodes];
    for bf in disc.mesh.boundary_facets(boundary)? {
        let nodes = vf.nodes.cell(bf.cell);
        for k in disc.velocity_element.facet_nodes(bf.facet) {
            on_boundary[nodes[k]] = true;
        }
    }
    debug_assert_eq!(raw.len(), n);
    let mut f = [0.0; D];
    for (node, _) in on_boundary.iter().enumerate().filter(|(_, &b)| b) {
        for a in 0..D {
            f[a] -= raw[vf.dof(node, a)];
        }
    }
    f.iter_mut().for_each(|v| *v *= problem.formulation.around());
    Ok(f)
}

/// The time level a quantity is evaluated at: steady (`inv_dt = 0`, no history) or a step of
/// the time loop.
#[derive(Clone, Copy, Debug, Default)]
pub struct StepState<'a> {
    pub time: f64,
    pub inv_dt: f64,
    pub u_star: Option<&'a [f64]>,
}

/// Evaluates a boundary integral (times its `scale`).
pub fn boundary_integral<const D: usize>(
    disc: &FlowDiscretization<D>,
    problem: &FlowProblem<D>,
    x: &[f64],
    state: &StepState<'_>,
    spec: &BoundaryIntegralSpec,
) -> Result<f64, FlowError> {
    let formulation = problem.formulation;
    if spec.kind == BoundaryIntegralKind::Force {
        return Ok(spec.scale * boundary_force(disc, problem, x, state, &spec.boundary)?[spec.component]);
    }
    let facets = disc.mesh.boundary_facets(&spec.boundary)?;
    let mut fv = disc.facet_values();
    let vf = &disc.velocity_field();
    let pf = &disc.pressure_field();
    let applied: Vec<&crate::discretize::flow::TractionBc<D>> = problem.traction.iter().filter(|bc| bc.boundary == spec.boundary).collect();
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
                BoundaryIntegralKind::Force => unreachable!("forces return above"),
                BoundaryIntegralKind::AppliedTraction => {
                    let n = &fv.normal[q];
                    for bc in &applied {
                        let t = (bc.traction)(&xq, n, state.time);
                        num -= w * (0..D).map(|a| t[a] * n[a]).sum::<f64>();
                    }
                    den += w;
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
    Ok(spec.scale
        * match spec.kind {
            BoundaryIntegralKind::Flux => formulation.around() * num,
            BoundaryIntegralKind::MeanPressure | BoundaryIntegralKind::AppliedTraction => num / den,
            _ => num,
        })
}

/// Evaluates a quantity of the domain (or of its slab).
pub fn domain_quantity<const D: usize>(disc: &FlowDiscretization<D>, x: &[f64], spec: &DomainQuantitySpec) -> f64 {
    match spec.kind {
        DomainQuantityKind::MaxSpeed => max_speed(disc, x, spec.slab.as_ref()),
    }
}

/// `max |u|` over the vertices, edge midpoints and centroid of every cell (in reference
/// coordinates, so curved cells are sampled at the images of these points), or over those of
/// them that lie in `slab` (`NaN` where none does: a slab beside the mesh, or in other units).
pub fn max_speed<const D: usize>(disc: &FlowDiscretization<D>, x: &[f64], slab: Option<&SlabSpec>) -> f64 {
    let cell = disc.velocity_element.cell();
    let verts: Vec<[f64; D]> = cell.vertices().iter().map(|v| std::array::from_fn(|d| v[d])).collect();
    let mut points: Vec<[f64; D]> = verts.clone();
    for i in 0..verts.len() {
        for j in i + 1..verts.len() {
            points.push(std::array::from_fn(|d| 0.5 * (verts[i][d] + verts[j][d])));
        }
    }
    points.push(cell.centroid());
    let tab = disc.velocity_element.tabulate(&points);
    let n = disc.velocity_element.num_dofs();
    let geometry = disc.mesh.geometry_element();
    let (geometry_tab, m) = (geometry.tabulate(&points), geometry.num_dofs());
    let vf = &disc.velocity_field();
    let mut coords = Vec::new();
    (0..disc.mesh.num_cells())
        .map(|c| {
            let nodes = vf.nodes.cell(c);
            disc.mesh.cell_coords_into(c, &mut coords);
            let inside = |q: usize| {
                slab.is_none_or(|slab| {
                    let phi = &geometry_tab.values[q * m..(q + 1) * m];
                    slab.contains(&std::array::from_fn::<f64, D, _>(|d| coords.iter().zip(phi).map(|(p, v)| v * p[d]).sum()))
                })
            };
            (0..points.len())
                .filter(|&q| inside(q))
                .map(|q| {
                    let phi = &tab.values[q * n..(q + 1) * n];
                    (0..D).map(|a| nodes.iter().zip(phi).map(|(&node, v)| v * x[vf.dof(node, a)]).sum::<f64>().powi(2)).sum::<f64>().sqrt()
                })
                .fold(f64::NAN, f64::max)
        })
        .fold(f64::NAN, f64::max)
}

/// Every flow quantity a case requests, in the order probes, boundary integrals, domain
/// quantities, combinations, after the state of each Windkessel outlet ([`windkessel_states`]).
/// Combinations may also use the quantities in `known` (evaluated elsewhere: the solid's probes,
/// the built-in quantities of FSI runs). Displacement probes are left to the caller.
pub fn evaluate_all<const D: usize>(
    output: &crate::case::OutputSpec,
    disc: &FlowDiscretization<D>,
    problem: &FlowProblem<D>,
    x: &[f64],
    state: &StepState<'_>,
    known: &[(String, f64)],
) -> Result<Vec<(String, f64)>, QuantityError> {
    let mut out = windkessel_states(disc, problem, x);
    for p in output.probe.iter().filter(|p| p.field != crate::case::ProbeField::Displacement) {
        let v = probe(disc, x, p).ok_or_else(|| QuantityError::ProbeOutside { name: p.name.clone(), point: p.point.clone() })?;
        out.push((p.name.clone(), v));
    }
    for b in &output.boundary_integral {
        out.push((b.name.clone(), boundary_integral(disc, problem, x, state, b)?));
    }
    for q in &output.domain {
        out.push((q.name.clone(), domain_quantity(disc, x, q)));
    }
    for c in &output.combination {
        let value = |q: &str| out.iter().chain(known).find(|(n, _)| n == q).map_or(f64::NAN, |(_, v)| *v);
        let v = c.terms.iter().map(|(q, k)| k * value(q)).sum();
        out.push((c.name.clone(), v));
    }
    Ok(out)
}

/// The state of each Windkessel outlet `NAME` (its boundary): `NAME_flux` (`Q`),
/// `NAME_pressure` (the outlet pressure `R_p Q + P_c`) and `NAME_capacitor_pressure` (`P_c`).
pub fn windkessel_states<const D: usize>(disc: &FlowDiscretization<D>, problem: &FlowProblem<D>, x: &[f64]) -> Vec<(String, f64)> {
    let mut out = Vec::new();
    for (k, wk) in problem.windkessel.iter().enumerate() {
        let (iq, ic) = disc.windkessel_dofs(k);
        let name = &wk.boundary;
        let values = [x[iq], wk.outlet_pressure(x[iq], x[ic]), x[ic]];
        out.extend(WINDKESSEL_QUANTITIES.iter().zip(values).map(|(q, v)| (format!("{name}_{q}"), v)));
    }
    out
}

/// A quantity that cannot be evaluated.
#[derive(Debug, thiserror::Error)]
pub enum QuantityError {
    #[error("probe '{name}' at {point:?} lies outside the fluid mesh")]
    ProbeOutside { name: String, point: Vec<f64> },
    #[error(transparent)]
    Flow(#[from] FlowError),
}

/// One point of a profile.
#[derive(Clone, Copy, Debug)]
pub struct ProfilePoint<const D: usize> {
    /// Arc length along the boundary (2D: along the chain of facets, increasing counter-clockwise
    /// around the fluid; disconnected pieces follow each other; 3D: the coordinate along the
    /// largest extent of the boundary).
    pub s: f64,
    pub x: [f64; D],
    pub value: f64,
}

/// Facets of a 2D boundary in walking order, each with a flag saying whether it is walked
/// against its vertex order. Disconnected pieces follow each other.
fn chain_facets<const D: usize>(disc: &FlowDiscretization<D>, facets: &[fdfsi_fem::mesh::BoundaryFacet]) -> Vec<(usize, bool)> {
    use std::collections::HashMap;
    let ends = |k: usize| -> [usize; 2] {
        let bf = facets[k];
        let v = disc.mesh.cell_vertices(bf.cell);
        let fv = disc.mesh.cell_type.facet(bf.facet);
        [v[fv[0]], v[fv[1]]]
    };
    let mut at: HashMap<usize, Vec<usize>> = HashMap::new();
    for k in 0..facets.len() {
        for v in ends(k) {
            at.entry(v).or_default().push(k);
        }
    }
    let mut used = vec![false; facets.len()];
    let mut order = Vec::with_capacity(facets.len());
    // Facets are oriented counter-clockwise around the fluid (outward normal on the right of the
    // walking direction); an open piece is walked from the facet whose first vertex is free.
    while let Some(start) = (0..facets.len()).filter(|&k| !used[k]).min_by_key(|&k| usize::from(at[&ends(k)[0]].len() != 1)) {
        let mut from = ends(start)[0];
        let mut k = start;
        loop {
            used[k] = true;
            let e = ends(k);
            let reversed = e[0] != from;
            order.push((k, reversed));
            let to = if reversed { e[0] } else { e[1] };
            match at[&to].iter().copied().find(|&j| !used[j]) {
                Some(j) => {
                    from = to;
                    k = j;
                }
                None => break,
            }
        }
    }
    order
}

/// The profile of `spec` along its boundary.
pub fn profile<const D: usize>(
    disc: &FlowDiscretization<D>,
    problem: &FlowProblem<D>,
    x: &[f64],
    spec: &crate::case::ProfileSpec,
) -> Result<Vec<ProfilePoint<D>>, FlowError> {
    use crate::case::ProfileKind;
    let facets = disc.mesh.boundary_facets(&spec.boundary)?;
    let order: Vec<(usize, bool)> = if D == 2 { chain_facets(disc, &facets) } else { (0..facets.len()).map(|k| (k, false)).collect() };
    let mut fv = disc.facet_values();
    let vf = &disc.velocity_field();
    let pf = &disc.pressure_field();
    let eta = problem.params.viscosity;
    let mut coords = Vec::new();
    let mut pts: Vec<ProfilePoint<D>> = Vec::new();
    let mut psi = [0.0; 4];
    for (k, reversed) in order {
        let bf = facets[k];
        disc.mesh.cell_coords_into(bf.cell, &mut coords);
        fv.reinit(&coords, bf.facet).map_err(|source| FlowError::Map { cell: bf.cell, source })?;
        let nodes = vf.nodes.cell(bf.cell);
        let centroid = cell_centroid(disc, bf.cell);
        let nq = fv.num_points();
        let qs: Vec<usize> = if reversed { (0..nq).rev().collect() } else { (0..nq).collect() };
        // Walking direction along this facet (2D): from its first to its last point.
        let (first, last) = (fv.x[qs[0]], fv.x[qs[nq - 1]]);
        let mut dir: [f64; D] = std::array::from_fn(|d| last[d] - first[d]);
        let len = dir.iter().map(|v| v * v).sum::<f64>().sqrt().max(f64::MIN_POSITIVE);
        dir.iter_mut().for_each(|v| *v /= len);
        for &q in &qs {
            let n = fv.normal[q];
            let value = match spec.kind {
                ProfileKind::Pressure => {
                    p1disc_basis(&fv.x[q], &centroid, &mut psi);
                    (0..=D).map(|k| x[pf.dof(bf.cell * (D + 1) + k, 0)] * psi[k]).sum()
                }
                ProfileKind::WallShearStress => {
                    let mut g = [[0.0; D]; D];
                    for (i, &node) in nodes.iter().enumerate() {
                        for a in 0..D {
                            for b in 0..D {
                                g[a][b] += x[vf.dof(node, a)] * fv.grad_phi(q)[i][b];
                            }
                        }
                    }
                    // Traction of the fluid on the wall: minus the stress on the fluid's outward normal.
                    let tau: [f64; D] = std::array::from_fn(|a| -eta * (0..D).map(|b| (g[a][b] + g[b][a]) * n[b]).sum::<f64>());
                    let tn: f64 = (0..D).map(|a| tau[a] * n[a]).sum();
                    let tt: [f64; D] = std::array::from_fn(|a| tau[a] - tn * n[a]);
                    if D == 2 {
                        (0..D).map(|a| tt[a] * dir[a]).sum()
                    } else {
                        tt.iter().map(|v| v * v).sum::<f64>().sqrt()
                    }
                }
            };
            pts.push(ProfilePoint { s: 0.0, x: fv.x[q], value });
        }
    }
    if D == 2 {
        for i in 1..pts.len() {
            let d: f64 = (0..D).map(|a| (pts[i].x[a] - pts[i - 1].x[a]).powi(2)).sum::<f64>().sqrt();
            pts[i].s = pts[i - 1].s + d;
        }
    } else if !pts.is_empty() {
        let axis = (0..D)
            .max_by(|&a, &b| {
                let ext = |a: usize| pts.iter().map(|p| p.x[a]).fold(f64::MIN, f64::max) - pts.iter().map(|p| p.x[a]).fold(f64::MAX, f64::min);
                ext(a).total_cmp(&ext(b))
            })
            .unwrap_or(0);
        let lo = pts.iter().map(|p| p.x[axis]).fold(f64::MAX, f64::min);
        pts.iter_mut().for_each(|p| p.s = p.x[axis] - lo);
        pts.sort_by(|a, b| a.s.total_cmp(&b.s));
    }
    Ok(pts)
}

/// Writes a profile as CSV with columns `s,x,y[,z],value`.
pub fn profile_csv<const D: usize>(pts: &[ProfilePoint<D>]) -> String {
    let mut out = String::from(if D == 2 { "s,x,y,value\n" } else { "s,x,y,z,value\n" });
    for p in pts {
        out.push_str(&format!("{:.12e}", p.s));
        for d in 0..D {
            out.push_str(&format!(",{:.12e}", p.x[d]));
        }
        out.push_str(&format!(",{:.12e}\n", p.value));
    }
    out
}
