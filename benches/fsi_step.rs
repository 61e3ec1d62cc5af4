//! Benchmark of one monolithic FSI step (paper section 2): adapt the original fluid mesh to
//! gamma_s, build the dof maps, coupling elements and pattern, transfer the velocity, Newton with
//! the sparse LU to convergence, update the solid.
//!
//! Systems, built from the built-in cases through the same code as `fdfsi run`, each taken after
//! `warm` steps from rest so that the fluid moves and the solid is deformed:
//!
//! * `model-problem-1`: the flexible slab in pulsatile flow (about 29 800 dofs), after 20 steps;
//! * `model-problem-2`: the stiff skewed plate on the 64 x 16 (about 11 500 dofs) and
//!   128 x 32 (about 45 000 dofs) channel meshes, after 3 steps;
//! * `model-problem-4`: the membrane across the quarter pipe (3D) on the coarse mesh of the CI
//!   test (468 tetrahedra, 30 hexahedra, about 9 800 dofs), after 3 steps, with the case's Newton
//!   options (one factorisation per step). The full-size problem (70 000 dofs, 25-30 s per step)
//!   is measured by its run's `summary.json` (BENCHMARKS.md).
//!
//! Besides criterion's time per step, the split of one step by phase (as `summary.json` reports
//! it) is printed.
//!
//! Run: `cargo bench --bench fsi_step` (numbers in BENCHMARKS.md).

use criterion::{criterion_group, criterion_main, Criterion};
use fdfsi::case::builtin::BUILTIN_CASES;
use fdfsi::case::Case;
use fdfsi::discretize::fsi::{step, FsiModel, FsiState};
use fdfsi::fem::gmsh::AnyMesh;
use fdfsi::fem::mesh::Mesh;
use fdfsi::setup::build_mesh;
use fdfsi::solve::linear::FaerLu;
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

fn bench_case(c: &mut Criterion, name: &str, edit: impl Fn(String) -> String, warm: usize) {
    let text = edit(BUILTIN_CASES.iter().find(|(n, _)| *n == name).expect("built-in case").1.to_string());
    let case = Case::from_toml_str(&text, name).expect("case");
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let label = format!("{name}{}", if text.contains("n = [128, 32]") { "-128x32" } else { "" });
    match build_mesh(&case, &dir).expect("mesh") {
        AnyMesh::D2(mesh) => bench_model::<2>(c, &label, &case, &mesh, &dir, warm),
        AnyMesh::D3(mesh) => bench_model::<3>(c, &label, &case, &mesh, &dir, warm),
    }
}

fn bench_model<const D: usize>(c: &mut Criterion, label: &str, case: &Case, mesh: &Mesh<D>, dir: &Path, warm: usize) {
    let model: FsiModel<D> = fdfsi::setup::fsi_model(case, mesh, dir).expect("model");
    let dt = case.time.as_ref().expect("time").dt;
    let newton = case.solver.newton.clone();
    let mut state = FsiState::at_rest(&model);
    for _ in 0..warm {
        state = step(&model, &state, dt, &mut FaerLu::default(), &newton).expect("warm-up step").0;
    }
    let (_, st) = step(&model, &state, dt, &mut FaerLu::default(), &newton).expect("step");
    let r = &st.report;
    eprintln!(
        "{label}: dofs {} + {} + {}, {} coupling elements, {} Newton iterations; phases (s): adapt {:.4}, build {:.4}, transfer {:.4}, newton {:.4} (assemble {:.4}, factorize {:.4}, solve {:.4}), update {:.4}",
        r.fluid_dofs,
        r.solid_dofs,
        r.multiplier_dofs,
        r.coupling_elements,
        r.newton.iterations,
        r.seconds.adapt,
        r.seconds.build,
        r.seconds.transfer,
        r.seconds.newton,
        r.newton.assemble_seconds,
        r.newton.factorize_seconds,
        r.newton.solve_seconds,
        r.seconds.update
    );
    let mut group = c.benchmark_group(label);
    group.sample_size(10).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(20));
    // Every step adapts the mesh anew; a run keeps its solver, which redoes the symbolic
    // factorisation when the pattern changed (almost every step while the solid moves). A fresh
    // solver per sample measures that case.
    group.bench_function("fsi_step", |b| b.iter(|| black_box(step(&model, &state, dt, &mut FaerLu::default(), &newton).expect("step"))));
    group.finish();
}

fn benches(c: &mut Criterion) {
    bench_case(c, "model-problem-1", |t| t, 20);
    bench_case(c, "model-problem-2", |t| t, 3);
    bench_case(c, "model-problem-2", |t| t.replace("n = [64, 16]", "n = [128, 32]"), 3);
    bench_case(
        c,
        "model-problem-4",
        |t| t.replace("n_radial = 8\nn_axial = 12", "n_radial = 4\nn_axial = 6").replace("n_core = 6, n_ring = 4", "n_core = 3, n_ring = 2"),
        3,
    );
}

criterion_group!(fsi_step, benches);
criterion_main!(fsi_step);
