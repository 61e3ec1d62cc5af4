//! The README's tutorial (`tutorial/`): the Gmsh meshes shipped beside their `.geo` files have the
//! groups those files name, and the tutorial case runs as FSI. CI has no Gmsh: the `.msh` files
//! are committed, made by `gmsh -2 channel.geo` and `gmsh -2 leaflet.geo`.

use fdfsi::case::Case;
use fdfsi::fem::element::ReferenceCell;
use fdfsi::fem::gmsh::{read_msh, AnyMesh};
use fdfsi::run::{run_case, RunOptions};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn tutorial() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tutorial")
}

/// The names of the `Physical Curve("...")` (dimension 1) and `Physical Surface("...")`
/// (dimension 2) groups of a `.geo` file.
fn physical_names(geo: &str) -> (Vec<String>, Vec<String>) {
    let names = |kind: &str| {
        geo.lines()
            .filter_map(|l| l.trim().strip_prefix(&format!("Physical {kind}(\"")))
            .map(|rest| rest.split('"').next().unwrap().to_string())
            .collect::<Vec<_>>()
    };
    (names("Curve"), names("Surface"))
}

#[test]
fn tutorial_meshes_have_the_groups_their_geo_files_name() {
    for (name, cell, nodes) in [("channel", ReferenceCell::Triangle, 3), ("leaflet", ReferenceCell::Quadrilateral, 9)] {
        let geo = std::fs::read_to_string(tutorial().join(format!("{name}.geo"))).unwrap();
        let (curves, surfaces) = physical_names(&geo);
        assert!(curves.len() >= 4 && surfaces.len() == 1, "{name}.geo: {curves:?} {surfaces:?}");
        let AnyMesh::D2(mesh) = read_msh(&tutorial().join(format!("{name}.msh"))).unwrap() else { panic!("{name}.msh is not 2D") };
        let boundaries: Vec<&str> = mesh.boundary_names.iter().map(|(n, _)| n.as_str()).collect();
        let regions: Vec<&str> = mesh.region_names.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(boundaries.len(), curves.len(), "{name}.msh has the boundaries {boundaries:?}, {name}.geo names {curves:?}");
        assert!(curves.iter().all(|c| boundaries.contains(&c.as_str())), "{name}.msh has the boundaries {boundaries:?}, {name}.geo names {curves:?}");
        assert_eq!(regions, surfaces, "{name}.msh");
        assert_eq!((mesh.cell_type, mesh.cell(0).len()), (cell, nodes), "{name}.msh: the element Gmsh was asked for");
    }
}

/// What the README's tutorial says `fdfsi check tutorial/leaflet.toml` reports.
#[test]
fn tutorial_case_checks_as_the_readme_says() {
    let case = Case::read(&tutorial().join("leaflet.toml")).unwrap();
    let report = fdfsi::run::check_case(&case, "tutorial/leaflet.toml", &tutorial()).unwrap();
    for said in ["8006 cells", "on 20 cells", "total 73529", "40 time steps"] {
        assert!(report.contains(said), "`fdfsi check` does not say {said:?}: {report}");
    }
}

#[test]
fn tutorial_case_runs_as_fsi() {
    let mut case = Case::read(&tutorial().join("leaflet.toml")).unwrap();
    case.time.as_mut().unwrap().end = 0.5; // the first 10 of its 40 steps
    let out = std::env::temp_dir().join(format!("fdfsi-test-tutorial-{}", std::process::id()));
    let summary = run_case(&case, &RunOptions::new(out.clone(), tutorial()), &mut |_: &str| {}).unwrap();
    assert_eq!(summary.steps, 10);
    assert!(summary.dofs["solid"] > 0 && summary.dofs["multiplier"] > 0, "{:?}", summary.dofs);
    // history.csv: what flows in leaves (the fluid is incompressible), and the flow pushes the
    // tip downstream, further every step.
    let text = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows: Vec<BTreeMap<&str, f64>> = lines.map(|l| header.iter().copied().zip(l.split(',').map(|v| v.parse().unwrap())).collect()).collect();
    let mut tip = 0.0;
    for r in rows.iter().filter(|r| r["step"] > 0.0) {
        assert!((r["inlet_flux"] + r["outlet_flux"]).abs() < 1e-9, "step {}: {} in, {} out", r["step"], r["inlet_flux"], r["outlet_flux"]);
        assert!(r["tip_displacement_x"] > tip, "step {}: the tip at {} after {tip}", r["step"], r["tip_displacement_x"]);
        tip = r["tip_displacement_x"];
    }
    assert!(out.join("speed.png").exists() && out.join("animation.gif").exists());
    std::fs::remove_dir_all(&out).ok();
}
