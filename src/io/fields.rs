//! The solution fields as VTK grids: the fluid on its mesh, the deformed solid, gamma_f with the
//! multiplier.

use super::OutputError;
use crate::discretize::flow::FlowDiscretization;
use crate::discretize::solid::{pressure_at, SolidDiscretization, SolidProblem};
use crate::physics::solid::{det3, matmul, transpose};
use fdfsi_fem::vtk::{UnstructuredGrid, VtkCellType, VtkError};

/// The fluid solution as a VTK grid of quadratic cells.
pub fn fluid_grid<const D: usize>(disc: &FlowDiscretization<D>, x: &[f64]) -> Result<UnstructuredGrid, VtkError> {
    let vf = &disc.velocity_field();
    let pf = &disc.pressure_field();
    let (cell_type, corner_nodes) = if D == 2 { (VtkCellType::QuadraticTriangle, 6) } else { (VtkCellType::QuadraticTetra, 10) };
    // The P2 nodes (vertices and edges) come first in the velocity numbering.
    let num_p2 = disc.topology.num_vertices + disc.topology.edges.len();
    let points: Vec<[f64; 3]> = disc.velocity_nodes[..num_p2].iter().map(|p| std::array::from_fn(|d| if d < D { p[d] } else { 0.0 })).collect();
    let mut grid = UnstructuredGrid::new(points);
    for c in 0..disc.mesh.num_cells() {
        grid.push_cell(cell_type, &vf.nodes.cell(c)[..corner_nodes])?;
    }
    let mut vel = Vec::with_capacity(num_p2 * 3);
    for node in 0..num_p2 {
        for a in 0..3 {
            vel.push(if a < D { x[vf.dof(node, a)] } else { 0.0 });
        }
    }
    grid.add_point_data("velocity", 3, vel)?;
    let nc = disc.mesh.num_cells();
    let mut p = Vec::with_capacity(nc);
    let mut gp = Vec::with_capacity(nc * 3);
    for c in 0..nc {
        let dofs = &x[pf.dof(c * (D + 1), 0)..pf.dof(c * (D + 1), 0) + D + 1];
        p.push(dofs[0]);
        for a in 0..3 {
            gp.push(if a < D { dofs[a + 1] } else { 0.0 });
        }
    }
    grid.add_cell_data("pressure", 1, p)?;
    grid.add_cell_data("pressure_gradient", 3, gp)?;
    grid.add_cell_data("region", 1, disc.mesh.cell_tags.iter().map(|&t| t as f64).collect())?;
    Ok(grid)
}

/// gamma_f of an FSI step as a VTK grid: one line (2D) or triangle (3D) per coupling element,
/// with its own vertices because the multiplier is discontinuous between elements. Point data
/// `multiplier`: the P1 part of lambda (all of it with the paper's multiplier; with the
/// trace-mode multiplier its L2 projection onto P1 per element, and the mode's amplitude is cell
/// data `multiplier_trace_mode`), the traction of the fluid on the solid (force per unit length in 2D, per
/// unit area in 3D and per radian-length in axisymmetric runs); cell data `element`: the coupling
/// element's index.
pub fn gamma_f_grid<const D: usize>(disc: &crate::discretize::fsi::FsiDiscretization<D>, x: &[f64]) -> Result<UnstructuredGrid, VtkError> {
    let gamma_f = &disc.adapted.gamma_f;
    let points: Vec<[f64; 3]> = gamma_f
        .iter()
        .flat_map(|g| g.vertices.map(|v| disc.flow.mesh.points[v]))
        .map(|p| std::array::from_fn(|d| if d < D { p[d] } else { 0.0 }))
        .collect();
    let mut grid = UnstructuredGrid::new(points);
    let cell_type = if D == 2 { VtkCellType::Line } else { VtkCellType::Triangle };
    for e in 0..gamma_f.len() {
        grid.push_cell(cell_type, &(e * D..(e + 1) * D).collect::<Vec<_>>())?;
    }
    let mut lambda = Vec::with_capacity(gamma_f.len() * D * 3);
    for e in 0..gamma_f.len() {
        for k in 0..D {
            lambda.extend((0..3).map(|a| if a < D { x[disc.multiplier_dof(e, k, a)] } else { 0.0 }));
        }
    }
    grid.add_point_data("multiplier", 3, lambda)?;
    if !disc.coupling.mode.is_empty() {
        // The trace-mode multiplier's amplitude per element (its function is 1 at the vertices
        // and -1/2 mid-facet, and integrates to zero).
        let mode = (0..gamma_f.len())
            .flat_map(|e| (0..3).map(move |a| if a < D { x[disc.mode_multiplier_dof(disc.coupling.chain[e], a)] } else { 0.0 }))
            .collect();
        grid.add_cell_data("multiplier_trace_mode", 3, mode)?;
    }
    grid.add_cell_data("element", 1, (0..gamma_f.len()).map(|e| e as f64).collect())?;
    Ok(grid)
}

/// The deformed solid as a VTK grid: 9-node quadrilaterals / 27-node hexahedra with point data
/// `displacement` and cell data `pressure` (the mixed laws' pressure at the cell centre) and
/// `cauchy_stress` (the cell mean of `sigma = P F^T / J - p I` over its quadrature points, 9
/// components); with contact surfaces, point data `contact_pressure` and `contact_gap` (their
/// nodes' multiplier and gap to the plane or the other boundary, where none of it lies under a
/// node the distance to its nearest node; 0 elsewhere); for a fibre-reinforced law
/// `fibre_stretch` (the mean of `|F a_0| = sqrt(I4)` over the cell's quadrature points with a
/// fibre; 0 where it has none); with several bodies, cell data `body` (each cell's body, from 0).
pub fn solid_grid<const D: usize>(disc: &SolidDiscretization<D>, problem: &SolidProblem<D>, x: &[f64]) -> Result<UnstructuredGrid, OutputError> {
    let field = disc.displacement_field();
    let n = field.nodes.num_nodes;
    let points: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let u = disc.displacement(x, i);
            std::array::from_fn(|d| if d < D { disc.nodes_x0[i][d] + u[d] } else { 0.0 })
        })
        .collect();
    let mut grid = UnstructuredGrid::new(points);
    let ty = if D == 2 { VtkCellType::BiquadraticQuad } else { VtkCellType::TriquadraticHexahedron };
    let nc = disc.mesh.num_cells();
    for c in 0..nc {
        grid.push_cell(ty, field.nodes.cell(c))?;
    }
    let disp: Vec<f64> = (0..n)
        .flat_map(|i| {
            let u = disc.displacement(x, i);
            (0..3).map(move |d| if d < D { u[d] } else { 0.0 })
        })
        .collect();
    grid.add_point_data("displacement", 3, disp)?;
    if !disc.contact_surfaces().is_empty() {
        let (mut pressure, mut gap) = (vec![0.0; n], vec![0.0; n]);
        let position = |k: usize| -> [f64; D] {
            let u = disc.displacement(x, k);
            std::array::from_fn(|d| disc.nodes_x0[k][d] + u[d])
        };
        for (surface, nodes) in disc.contact_surfaces().iter().zip(disc.contact_gaps_and_weights(problem, x)) {
            for (j, &node) in surface.nodes.iter().enumerate() {
                pressure[node] = x[surface.first + j];
                // Where no master boundary lies under the node, the distance to the nearest
                // master node (a node far from the other boundary).
                let g = nodes[j].0;
                gap[node] = if g.is_finite() {
                    g
                } else {
                    let p = position(node);
                    let masters = surface.mortar.iter().flat_map(|m| &m.master_nodes);
                    masters.map(|&k| position(k)).map(|q| (0..D).map(|d| (q[d] - p[d]).powi(2)).sum::<f64>().sqrt()).fold(f64::INFINITY, f64::min)
                };
            }
        }
        grid.add_point_data("contact_pressure", 1, pressure)?;
        grid.add_point_data("contact_gap", 1, gap)?;
    }
    let f = disc.deformation_gradients(x)?;
    let nq = disc.points_per_cell();
    let (mut pressure, mut stress) = (Vec::with_capacity(nc), Vec::with_capacity(nc * 9));
    let mut fibre_stretch = Vec::with_capacity(nc);
    let (mut p_mat, mut tangent) = ([[0.0; 3]; 3], [[[[0.0; 3]; 3]; 3]; 3]);
    for c in 0..nc {
        let p_c = if disc.mixed { pressure_at(disc, x, c, &disc.centroid_x0[c]) } else { 0.0 };
        pressure.push(p_c);
        let material = problem.body(c).material.as_ref();
        let mut mean = [[0.0; 3]; 3];
        let (mut stretch, mut fibred) = (0.0, 0);
        for q in 0..nq {
            let fq = &f[c * nq + q];
            let x0: [f64; 3] = std::array::from_fn(|d| if d < D { disc.qp_x0[c * nq + q][d] } else { 0.0 });
            material.stress_tangent(fq, &x0, &mut p_mat, &mut tangent);
            if let Some(a0) = material.fibre_direction(&x0) {
                let fa: [f64; 3] = std::array::from_fn(|i| (0..3).map(|j| fq[i][j] * a0[j]).sum());
                stretch += fa.iter().map(|v| v * v).sum::<f64>().sqrt();
                fibred += 1;
            }
            let j = det3(fq);
            let p_q = if disc.mixed { pressure_at(disc, x, c, &disc.qp_x0[c * nq + q]) } else { 0.0 };
            let sigma = matmul(&p_mat, &transpose(fq));
            for a in 0..3 {
                for b in 0..3 {
                    mean[a][b] += (sigma[a][b] / j - if a == b { p_q } else { 0.0 }) / nq as f64;
                }
            }
        }
        stress.extend(mean.iter().flatten());
        fibre_stretch.push(if fibred > 0 { stretch / fibred as f64 } else { 0.0 });
    }
    grid.add_cell_data("pressure", 1, pressure)?;
    grid.add_cell_data("cauchy_stress", 9, stress)?;
    if fibre_stretch.iter().any(|&s| s > 0.0) {
        grid.add_cell_data("fibre_stretch", 1, fibre_stretch)?;
    }
    if problem.bodies.len() > 1 {
        grid.add_cell_data("body", 1, (0..nc).map(|c| problem.cell_body[c] as f64).collect())?;
    }
    Ok(grid)
}
