//! PNG line plots of a run's results: `fdfsi plot DIR`, and automatically at the end of
//! `fdfsi run`. Into `DIR/plots/`:
//! - `NAME.png`: every column of `history.csv` (other than `step` and `time`) against time;
//! - `trajectory_STEM.png`: for every pair of columns `STEM_x`, `STEM_y` (for example the probes
//!   `tip_displacement_x` / `tip_displacement_y`) or `ux_STEM`, `uy_STEM` (the Turek-Hron cases'
//!   `ux_A` / `uy_A`), the path of the pair over the run;
//! - `profile_NAME.png`: every `profiles/NAME.csv`, its value against the arc length `s`.
//!
//! A history of one row (a steady run) gives no plots against time.
//!
//! Text is drawn with the DejaVu Sans Mono font compiled into the binary
//! (`assets/fonts/DejaVuSansMono.ttf`, free licence in `assets/fonts/DejaVu-LICENSE`), so plots
//! need no system fonts or libraries. Every PNG is drawn under a temporary name and renamed.

use plotters::prelude::*;
use plotters::style::FontStyle;
use std::path::{Path, PathBuf};
use std::sync::Once;
use thiserror::Error;

/// The font compiled into the binary.
const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSansMono.ttf");
pub(crate) const FAMILY: &str = "sans-serif";

/// A plotting failure.
#[derive(Debug, Error)]
pub enum PlotError {
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("{path}: line {line}: {message}")]
    Csv { path: String, line: usize, message: String },
    #[error("{path}: drawing failed: {message}")]
    Draw { path: String, message: String },
    #[error("{path}: no history.csv and no profiles to plot")]
    Nothing { path: String },
}

/// One named curve.
#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
}

/// A table read from a CSV file with a header row of column names.
#[derive(Clone, Debug, Default)]
pub struct Table {
    pub columns: Vec<String>,
    pub rows: Vec<Vec<f64>>,
}

impl Table {
    /// Reads a CSV file of numbers with a header row (empty lines are skipped).
    pub fn read(path: &Path) -> Result<Self, PlotError> {
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| PlotError::Io { path: shown.clone(), source })?;
        let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
        let Some((_, header)) = lines.next() else {
            return Err(PlotError::Csv { path: shown, line: 1, message: "the file is empty".into() });
        };
        let columns: Vec<String> = header.split(',').map(|c| c.trim().to_string()).collect();
        let mut rows = Vec::new();
        for (i, line) in lines {
            let row: Result<Vec<f64>, _> = line.split(',').map(|v| v.trim().parse::<f64>()).collect();
            let row = row.map_err(|e| PlotError::Csv { path: shown.clone(), line: i + 1, message: e.to_string() })?;
            if row.len() != columns.len() {
                let message = format!("{} values for {} columns", row.len(), columns.len());
                return Err(PlotError::Csv { path: shown, line: i + 1, message });
            }
            rows.push(row);
        }
        Ok(Table { columns, rows })
    }

    /// The column named `name`.
    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let j = self.columns.iter().position(|c| c == name)?;
        Some(self.rows.iter().map(|r| r[j]).collect())
    }

    /// Column `y` against column `x`, leaving out rows where either is not finite.
    pub fn series(&self, x: &str, y: &str) -> Option<Series> {
        let (xs, ys) = (self.column(x)?, self.column(y)?);
        let points = xs.into_iter().zip(ys).filter(|(a, b)| a.is_finite() && b.is_finite()).collect();
        Some(Series { name: y.to_string(), points })
    }
}

pub(crate) fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bytes are a valid TrueType font compiled in; a failure would only lose the text.
        let _ = plotters::style::register_font(FAMILY, FontStyle::Normal, FONT);
    });
}

/// Draws `series` as lines (with markers when a curve has few points) into the PNG `path`.
pub fn line_plot(path: &Path, title: &str, x_label: &str, y_label: &str, series: &[Series]) -> Result<(), PlotError> {
    register_font();
    let shown = path.display().to_string();
    let draw_err = |e: &dyn std::fmt::Display| PlotError::Draw { path: shown.clone(), message: e.to_string() };
    let tmp = path.with_extension("tmp.png");
    let (x_range, y_range) = ranges(series);
    {
        let root = BitMapBackend::new(&tmp, (900, 560)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| draw_err(&e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, (FAMILY, 22))
            .margin(14)
            .x_label_area_size(46)
            .y_label_area_size(90)
            .build_cartesian_2d(x_range, y_range)
            .map_err(|e| draw_err(&e))?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .label_style((FAMILY, 14))
            .axis_desc_style((FAMILY, 16))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(|e| draw_err(&e))?;
        for (k, s) in series.iter().enumerate() {
            let colour = Palette99::pick(k).to_rgba();
            let style = ShapeStyle::from(colour).stroke_width(2);
            chart
                .draw_series(LineSeries::new(s.points.iter().copied(), style))
                .map_err(|e| draw_err(&e))?
                .label(s.name.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style));
            if s.points.len() <= 40 {
                chart.draw_series(s.points.iter().map(|&p| Circle::new(p, 3, colour.filled()))).map_err(|e| draw_err(&e))?;
            }
        }
        if series.len() > 1 {
            chart
                .configure_series_labels()
                .label_font((FAMILY, 14))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()
                .map_err(|e| draw_err(&e))?;
        }
        root.present().map_err(|e| draw_err(&e))?;
    }
    std::fs::rename(&tmp, path).map_err(|source| PlotError::Io { path: shown, source })
}

/// Axis ranges covering every finite point, widened a little (and made non-empty).
fn ranges(series: &[Series]) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for &(x, y) in series.iter().flat_map(|s| &s.points) {
        for (d, v) in [x, y].into_iter().enumerate() {
            lo[d] = lo[d].min(v);
            hi[d] = hi[d].max(v);
        }
    }
    let range = |d: usize| {
        if !lo[d].is_finite() {
            return 0.0..1.0;
        }
        let pad = 0.05 * (hi[d] - lo[d]).max(1e-12 * lo[d].abs().max(1.0));
        (lo[d] - pad)..(hi[d] + pad)
    };
    (range(0), range(1))
}

/// The pairs `(STEM, STEM_x, STEM_y)` and `(STEM, ux_STEM, uy_STEM)` (Turek and Hron's names of
/// the displacement of a point) among `columns`.
fn trajectory_pairs(columns: &[String]) -> Vec<(String, String, String)> {
    columns
        .iter()
        .filter_map(|c| {
            let (stem, y) = match (c.strip_suffix("_x"), c.strip_prefix("ux_")) {
                (Some(stem), _) => (stem, format!("{stem}_y")),
                (None, Some(stem)) => (stem, format!("uy_{stem}")),
                (None, None) => return None,
            };
            columns.contains(&y).then(|| (stem.to_string(), c.clone(), y))
        })
        .collect()
}

/// Plots the results in `dir` (see the module documentation); returns the PNGs written.
pub fn plot_results(dir: &Path) -> Result<Vec<PathBuf>, PlotError> {
    plot_compared(dir, &[])
}

/// A run's results: its history (if any) and profiles (name, table).
struct Results {
    label: String,
    history: Option<Table>,
    profiles: Vec<(String, Table)>,
}

impl Results {
    fn read(dir: &Path) -> Result<Self, PlotError> {
        let history_path = dir.join("history.csv");
        let history = if history_path.exists() { Some(Table::read(&history_path)?) } else { None };
        let mut files: Vec<PathBuf> = match std::fs::read_dir(dir.join("profiles")) {
            Ok(entries) => entries.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.extension().is_some_and(|e| e == "csv")).collect(),
            Err(_) => Vec::new(),
        };
        files.sort();
        let mut profiles = Vec::new();
        for file in files {
            let table = Table::read(&file)?;
            if table.column("s").is_none() || table.column("value").is_none() {
                return Err(PlotError::Csv { path: file.display().to_string(), line: 1, message: "expected columns s and value".into() });
            }
            profiles.push((file.file_stem().and_then(|s| s.to_str()).unwrap_or("profile").to_string(), table));
        }
        if history.is_none() && profiles.is_empty() {
            return Err(PlotError::Nothing { path: dir.display().to_string() });
        }
        let label = dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| dir.display().to_string());
        Ok(Results { label, history, profiles })
    }

    /// The history columns worth plotting against time (none for a one-row, steady history).
    fn history_columns(&self) -> &[String] {
        match &self.history {
            Some(t) if t.rows.len() > 1 => &t.columns,
            _ => &[],
        }
    }

    fn history_series(&self, x: &str, y: &str) -> Option<Series> {
        let mut s = self.history.as_ref()?.series(x, y)?;
        s.name = self.label.clone();
        Some(s)
    }

    fn profile_series(&self, name: &str) -> Option<Series> {
        let (_, t) = self.profiles.iter().find(|(n, _)| n == name)?;
        let mut s = t.series("s", "value")?;
        s.name = self.label.clone();
        Some(s)
    }
}

/// As [`plot_results`], with the same quantities and profiles of the runs in `others` drawn
/// into the same plots (each curve labelled with its folder's name): `fdfsi plot DIR --with
/// OTHER`, e.g. an FSI run against its pure-fluid twin.
pub fn plot_compared(dir: &Path, others: &[PathBuf]) -> Result<Vec<PathBuf>, PlotError> {
    let main = Results::read(dir)?;
    let others: Vec<Results> = others.iter().map(|d| Results::read(d)).collect::<Result<_, _>>()?;
    let plots = dir.join("plots");
    std::fs::create_dir_all(&plots).map_err(|source| PlotError::Io { path: plots.display().to_string(), source })?;
    let all = || std::iter::once(&main).chain(&others);
    let mut written = Vec::new();
    let mut draw = |file: String, title: &str, x_label: &str, y_label: &str, series: Vec<Series>| -> Result<(), PlotError> {
        // A quantity of one of several solids, `upper/bottom_contact_force`, is drawn to
        // `upper.bottom_contact_force.png`, in the folder.
        let path = plots.join(file.replace('/', "."));
        let mut series = series;
        if series.len() == 1 {
            series[0].name = y_label.to_string();
        }
        line_plot(&path, title, x_label, y_label, &series)?;
        written.push(path);
        Ok(())
    };
    // Krylov iterations only where a Krylov solver ran (a direct solve writes zeros).
    let all_zero = |name: &str| main.history.as_ref().and_then(|t| t.column(name)).is_some_and(|v| v.iter().all(|&x| x == 0.0));
    let skipped = |c: &str| matches!(c, "step" | "time") || (c == "krylov_iterations" && all_zero(c));
    let plotted = |c: &&String| !skipped(c);
    for name in main.history_columns().iter().filter(plotted) {
        let series = all().filter_map(|r| r.history_series("time", name)).collect();
        draw(format!("{name}.png"), name, "time", name, series)?;
    }
    for (stem, x, y) in trajectory_pairs(main.history_columns()) {
        let series = all().filter_map(|r| r.history_series(&x, &y)).collect();
        draw(format!("trajectory_{stem}.png"), &format!("{stem}: path over the run"), &x, &y, series)?;
    }
    for (name, _) in &main.profiles {
        let series = all().filter_map(|r| r.profile_series(name)).collect();
        draw(format!("profile_{name}.png"), name, "arc length s", "value", series)?;
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plots_history_columns_trajectories_and_profiles() {
        let dir = tempfile::tempdir().unwrap();
        let mut text = String::from("step,time,newton_iterations,residual,tip_x,tip_y\n");
        for k in 0..30 {
            let t = k as f64 * 0.1;
            text.push_str(&format!("{k},{t},3,1e-12,{},{}\n", t.sin(), t.cos()));
        }
        std::fs::write(dir.path().join("history.csv"), text).unwrap();
        std::fs::create_dir(dir.path().join("profiles")).unwrap();
        std::fs::write(dir.path().join("profiles/wss.csv"), "s,x,y,value\n0,0,0,1\n0.5,0.5,0,2\n1,1,0,1.5\n").unwrap();
        let written = plot_results(dir.path()).unwrap();
        let names: Vec<String> = written.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
        assert_eq!(names, ["newton_iterations.png", "residual.png", "tip_x.png", "tip_y.png", "trajectory_tip.png", "profile_wss.png"]);
        for p in &written {
            let bytes = std::fs::read(p).unwrap();
            assert_eq!(&bytes[1..4], b"PNG", "{}", p.display());
        }
        assert!(!dir.path().join("plots/tip_x.tmp.png").exists());
    }

    #[test]
    fn pairs_tip_x_tip_y_and_ux_a_uy_a() {
        let columns: Vec<String> = ["time", "tip_x", "tip_y", "ux_A", "uy_A", "ux_B", "drag_x"].iter().map(|s| s.to_string()).collect();
        let stems: Vec<String> = trajectory_pairs(&columns).into_iter().map(|p| p.0).collect();
        assert_eq!(stems, ["tip", "A"]);
    }

    #[test]
    fn another_run_is_drawn_into_the_same_plots() {
        let root = tempfile::tempdir().unwrap();
        let (a, b) = (root.path().join("fsi"), root.path().join("twin"));
        for (dir, scale) in [(&a, 1.0), (&b, 1.1)] {
            std::fs::create_dir_all(dir.join("profiles")).unwrap();
            std::fs::write(dir.join("profiles/wss.csv"), format!("s,x,y,value\n0,0,0,{scale}\n1,1,0,{}\n", 2.0 * scale)).unwrap();
        }
        let written = plot_compared(&a, std::slice::from_ref(&b)).unwrap();
        assert_eq!(written, [a.join("plots/profile_wss.png")]);
        let e = plot_compared(&a, &[root.path().join("missing")]).unwrap_err().to_string();
        assert!(e.contains("no history.csv and no profiles"), "{e}");
    }

    #[test]
    fn bad_inputs_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let e = plot_results(dir.path()).unwrap_err().to_string();
        assert!(e.contains("no history.csv and no profiles"), "{e}");
        std::fs::write(dir.path().join("history.csv"), "step,time,a\n0,0,1\n1,0.1,oops\n").unwrap();
        let e = plot_results(dir.path()).unwrap_err().to_string();
        assert!(e.contains("history.csv: line 3"), "{e}");
        std::fs::write(dir.path().join("history.csv"), "step,time,a\n0,0\n").unwrap();
        let e = plot_results(dir.path()).unwrap_err().to_string();
        assert!(e.contains("2 values for 3 columns"), "{e}");
    }
}
