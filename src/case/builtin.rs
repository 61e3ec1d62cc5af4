//! The cases built into the binary (`fdfsi cases`), the files of `cases/`.

/// The case built into the binary: `fdfsi run` with no case file runs it (the
/// [`BUILTIN_CASES`] entry [`DEFAULT_CASE_NAME`]).
pub const DEFAULT_CASE: &str = SLAB_ONE_BEAT;

const SLAB_ONE_BEAT: &str = include_str!("../../cases/slab-one-beat.toml");

/// The name `fdfsi run` gives the default case.
pub const DEFAULT_CASE_NAME: &str = "slab-one-beat";

/// Built-in cases: (name, TOML text). `fdfsi cases` lists them.
pub const BUILTIN_CASES: &[(&str, &str)] = &[
    ("channel-stokes", include_str!("../../cases/channel-stokes.toml")),
    ("pipe-axisymmetric-stokes", include_str!("../../cases/pipe-axisymmetric-stokes.toml")),
    ("quarter-pipe-3d-stokes", include_str!("../../cases/quarter-pipe-3d-stokes.toml")),
    ("cylinder-stokes-gmsh", include_str!("../../cases/cylinder-stokes-gmsh.toml")),
    ("schaefer-turek-2d1", include_str!("../../cases/schaefer-turek-2d1.toml")),
    ("lid-driven-cavity-re1000", include_str!("../../cases/lid-driven-cavity-re1000.toml")),
    ("womersley-axisymmetric", include_str!("../../cases/womersley-axisymmetric.toml")),
    ("skewed-plate-dirichlet", include_str!("../../cases/skewed-plate-dirichlet.toml")),
    ("model-problem-1", include_str!("../../cases/model-problem-1.toml")),
    ("slab-one-beat", SLAB_ONE_BEAT),
    ("model-problem-2", include_str!("../../cases/model-problem-2.toml")),
    ("model-problem-3", include_str!("../../cases/model-problem-3.toml")),
    ("model-problem-4", include_str!("../../cases/model-problem-4.toml")),
    ("model-problem-4-fine", include_str!("../../cases/model-problem-4-fine.toml")),
    ("cylinder-re100", include_str!("../../cases/cylinder-re100.toml")),
    ("slab-3d-poiseuille", include_str!("../../cases/slab-3d-poiseuille.toml")),
    ("cook-membrane", include_str!("../../cases/cook-membrane.toml")),
    ("cylinder-inflation-axisymmetric", include_str!("../../cases/cylinder-inflation-axisymmetric.toml")),
    ("turek-hron-csm1", include_str!("../../cases/turek-hron-csm1.toml")),
    ("turek-hron-csm2", include_str!("../../cases/turek-hron-csm2.toml")),
    ("turek-hron-csm3", include_str!("../../cases/turek-hron-csm3.toml")),
    ("turek-hron-cfd1", include_str!("../../cases/turek-hron-cfd1.toml")),
    ("turek-hron-cfd2", include_str!("../../cases/turek-hron-cfd2.toml")),
    ("turek-hron-cfd3", include_str!("../../cases/turek-hron-cfd3.toml")),
    ("turek-hron-fsi1", include_str!("../../cases/turek-hron-fsi1.toml")),
    ("turek-hron-fsi2", include_str!("../../cases/turek-hron-fsi2.toml")),
    ("turek-hron-fsi3", include_str!("../../cases/turek-hron-fsi3.toml")),
    ("fluid-film", include_str!("../../cases/fluid-film.toml")),
    ("valve-2d", include_str!("../../cases/valve-2d.toml")),
    ("valve-3d-sector", include_str!("../../cases/valve-3d-sector.toml")),
    ("valve-3d", include_str!("../../cases/valve-3d.toml")),
];
