//! The commands that read a run's results: `info`, `render`, `export`, `plot`, and `params`,
//! which reads a model's parameter schema. Each returns the text to print or the error.

use crate::fields::{self, Choice};
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// `cosim info`'s command line.
#[derive(Debug, clap::Args)]
pub struct InfoArgs {
    pub recording: PathBuf,
    /// Print the summary as one JSON document (nodes, couplings, windows, channels, the
    /// last balance row).
    #[arg(long)]
    pub json: bool,
}

/// `cosim render`'s command line.
#[derive(Debug, clap::Args)]
pub struct RenderArgs {
    /// The run's output folder.
    pub run: PathBuf,
    /// Simulated time (s) to draw (default: the last frames).
    #[arg(long, conflicts_with_all = ["all", "gif"])]
    pub time: Option<f64>,
    /// Colour NODE by one of its VTK fields (NODE.FIELD, e.g. gas.density, bar.velocity).
    #[arg(long)]
    pub field: Option<String>,
    /// Draw this node alone (its name as in the case, e.g. bar).
    #[arg(long, conflicts_with = "per_node")]
    pub node: Option<String>,
    /// Draw each node alone, one picture (or series, or GIF) per node:
    /// RUN/fields_<node>.png, RUN/frames/<node>_<k>.png, RUN/<node>.gif.
    #[arg(long)]
    pub per_node: bool,
    /// Every written frame: RUN/frames/fields_<k>.png (or <node>_<k>.png), k from 0.
    #[arg(long, conflicts_with = "gif")]
    pub all: bool,
    /// Every written frame as one animated GIF: RUN/fields.gif (or RUN/<node>.gif).
    #[arg(long)]
    pub gif: bool,
    /// Milliseconds per GIF frame.
    #[arg(long, default_value_t = 125, requires = "gif")]
    pub frame_ms: u32,
    /// The PNG (or GIF) file (default: RUN/fields.png, RUN/fields_<time>.png with --time,
    /// RUN/fields.gif with --gif).
    #[arg(long, short, conflicts_with_all = ["all", "per_node"])]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub view: ViewArgs,
}

/// The view of a picture of solids (`cosim render`, `cosim plot --field`).
#[derive(Debug, clap::Args)]
pub struct ViewArgs {
    /// The axis drawn upwards (x, y or z); the next axis in the cycle x → y → z → x is drawn
    /// across. Default: the bodies' second longest axis up, their longest across.
    #[arg(long, value_parser = ["x", "y", "z"])]
    pub up: Option<String>,
    /// Turn of the view about the up axis, degrees (0: a side view along the third axis;
    /// default 30).
    #[arg(long, allow_hyphen_values = true)]
    pub yaw: Option<f64>,
    /// Tilt of the view, degrees (positive: from above; default 20).
    #[arg(long, allow_hyphen_values = true)]
    pub pitch: Option<f64>,
}

impl ViewArgs {
    fn camera(&self) -> anyhow::Result<fields::Camera> {
        fields::Camera::from_args(self.up.as_deref(), self.yaw, self.pitch)
    }
}

/// `cosim export`'s command line.
#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// The run's output folder or its recording.
    pub run: PathBuf,
    #[arg(long, default_value = "npz", value_parser = ["npz", "csv", "parquet"])]
    pub format: String,
    /// Output file (npz) or directory (csv, parquet); default: RUN/history.npz or
    /// RUN/history/.
    #[arg(long, short)]
    pub output: Option<PathBuf>,
    /// Only these series: NODE/KEY with `*` as a wildcard, or NODE for all of its keys
    /// (`balance` is the coordinator's); repeatable or comma-separated.
    #[arg(long, value_delimiter = ',')]
    pub series: Vec<String>,
    /// Also write the interface fields of every coupling message to RUN/fields.npz
    /// (COUPLING/SENDER/FIELD as (messages, points, components), with .window and .time).
    #[arg(long)]
    pub fields: bool,
}

/// `cosim plot`'s command line.
#[derive(Debug, clap::Args)]
pub struct PlotArgs {
    /// Runs: output directories (holding run.mcap) or recordings.
    #[arg(required = true)]
    pub runs: Vec<PathBuf>,
    /// NODE.QUANTITY to plot (a scalar of the node's report, kinetic_energy,
    /// internal_energy, momentum_x, ...), repeatable: series that share a unit share a
    /// figure; a `*` in the quantity takes every match (`gas.point*.pressure`); `*.QUANTITY`:
    /// whichever node of each run reports it. Without any, each run's default set of charts
    /// (the one `cosim run` draws).
    #[arg(long = "series")]
    pub series: Vec<String>,
    /// Without `--series`: every quantity of every node on its own chart, not the default set.
    #[arg(long, conflicts_with_all = ["series", "x", "field", "fragments"])]
    pub all: bool,
    /// Instead of time histories, a picture of a field: NODE.FIELD of the node's VTK
    /// frames (e.g. gas.pressure, bar.damage), per run, at `--at` (default the end); of
    /// several runs also `runs_<field>.png`, all of them side by side on one colour range.
    #[arg(long, conflicts_with_all = ["series", "x"])]
    pub field: Option<String>,
    /// Instead of time histories, fragment-size histograms: per run, the widths and
    /// thicknesses of the fragments in each node's fragment table (its last frame).
    #[arg(long, conflicts_with_all = ["series", "x", "field"])]
    pub fragments: bool,
    /// Simulated time (s) of the field picture (the frame nearest it).
    #[arg(long, requires = "field")]
    pub at: Option<f64>,
    /// Draw the `--field` node alone, without the run's other nodes (a crash tube's shells
    /// without its joints' particles).
    #[arg(long, requires = "field")]
    pub alone: bool,
    /// Directory for the PNG files.
    #[arg(long, short, default_value = "plots")]
    pub output: PathBuf,
    /// NODE.QUANTITY for the horizontal axis instead of time (e.g. a displacement, for a
    /// force–displacement curve).
    #[arg(long)]
    pub x: Option<String>,
    /// The view of `--field` pictures of solids.
    #[command(flatten)]
    pub view: ViewArgs,
}

/// `cosim params`'s command line.
#[derive(Debug, clap::Args)]
pub struct ParamsArgs {
    /// A model: bar-1d, fem-2d, pd-bond, pd-correspondence, pd-rk-ba, euler, blt-shell,
    /// mc-spg, or one of `--solver`'s.
    pub model: Option<String>,
    /// Print the JSON Schema itself (for editors and tools) instead of the listing.
    #[arg(long)]
    pub json: bool,
    /// Ask this node executable instead of the built-in ones (one that supports --schema).
    #[arg(long)]
    pub solver: Option<PathBuf>,
}

/// `cosim info`: the recording's summary, as text or JSON.
pub(super) fn info(a: &InfoArgs) -> anyhow::Result<String> {
    let rec = recording_of(&a.recording);
    if a.json {
        Ok(serde_json::to_string_pretty(&crate::info::run_info(&rec)?)?)
    } else {
        crate::info::info(&rec)
    }
}

/// `cosim render`: the pictures drawn, a line each with the time it shows.
pub(super) fn render(a: RenderArgs) -> anyhow::Result<String> {
    let nodes: Vec<Option<String>> = if a.per_node {
        fields::nodes_with_series(&a.run)
            .into_iter()
            .map(Some)
            .collect()
    } else {
        vec![a.node.clone()]
    };
    let choice = a.field.as_deref().map(Choice::parse).transpose()?;
    let mut drawn = Vec::new();
    for node in &nodes {
        drawn.extend(render_node(&a, choice, node.as_deref())?);
    }
    if drawn.is_empty() {
        anyhow::bail!("{}: no node wrote a VTK series", a.run.display());
    }
    Ok(drawn_lines(&drawn))
}

/// What `cosim render` draws of one node (every node with `None`).
fn render_node(
    a: &RenderArgs,
    choice: Option<Choice>,
    node: Option<&str>,
) -> anyhow::Result<Vec<(PathBuf, f64)>> {
    let run = &a.run;
    if a.all {
        return fields::render_all(run, choice, node, a.view.camera()?);
    }
    if a.gif {
        let stem = node.unwrap_or("fields");
        let file = a
            .output
            .clone()
            .unwrap_or_else(|| run.join(format!("{stem}.gif")));
        let (n, t) = fields::render_gif(run, &file, choice, node, a.frame_ms, a.view.camera()?)?;
        eprintln!("{}: {n} frames", file.display());
        return Ok(vec![(file, t)]);
    }
    let png = a.output.clone().unwrap_or_else(|| match (a.time, node) {
        (Some(t), None) => run.join(format!("fields_{t:e}.png")),
        (Some(t), Some(n)) => run.join(format!("fields_{n}_{t:e}.png")),
        (None, None) => run.join("fields.png"),
        (None, Some(n)) => run.join(format!("fields_{n}.png")),
    });
    let t = fields::render(run, a.time, &png, choice, node, a.view.camera()?)?.time;
    Ok(vec![(png, t)])
}

/// One line per picture: its file and the simulated time it shows.
fn drawn_lines(drawn: &[(PathBuf, f64)]) -> String {
    let mut s = String::new();
    for (png, t) in drawn {
        let _ = writeln!(s, "{} (t = {t:e} s)", png.display());
    }
    s
}

/// `cosim export`: the histories (and with `--fields` the interface fields) written as
/// arrays; a line saying what and where.
pub(super) fn export(a: ExportArgs) -> anyhow::Result<String> {
    let rec = recording_of(&a.run);
    let base = folder_of(&a.run);
    let mut t = crate::export::tables(&rec)?;
    t.extend(crate::export::fragment_tables(&base)?);
    crate::export::filter(&mut t, &a.series)?;
    let note = if a.fields {
        export_fields(&rec, &base)?
    } else {
        String::new()
    };
    if a.format == "csv" || a.format == "parquet" {
        let dir = a.output.unwrap_or_else(|| base.join("history"));
        let files = if a.format == "csv" {
            crate::export::write_csv(&t, &dir)?
        } else {
            crate::export::write_parquet(&t, &dir)?
        };
        Ok(format!("{} tables in {}{note}", files.len(), dir.display()))
    } else {
        let f = a.output.unwrap_or_else(|| base.join("history.npz"));
        let n = crate::export::write_npz(&t, &f)?;
        Ok(format!("{n} arrays in {}{note}", f.display()))
    }
}

/// The interface fields of the recording `rec` written to `base/fields.npz`; the note that
/// says so.
fn export_fields(rec: &Path, base: &Path) -> anyhow::Result<String> {
    let (f, ragged) = crate::export::field_series(rec)?;
    let path = base.join("fields.npz");
    let n = crate::export::write_fields_npz(&f, &path)?;
    let mut note = format!("; {n} interface fields in {}", path.display());
    if !ragged.is_empty() {
        note += &format!(
            " (left out, their point count changes between messages: {})",
            ragged.join(", ")
        );
    }
    Ok(note)
}

/// `cosim plot`: the charts of the series written (or with `--field`, one picture per run,
/// and of several runs also one of them side by side on a shared colour range).
pub(super) fn plot(a: &PlotArgs) -> anyhow::Result<String> {
    if a.fragments {
        let runs: Vec<PathBuf> = a.runs.iter().map(|r| folder_of(r)).collect();
        let files = crate::histogram::fragment_histograms(&runs, &a.output)?;
        return Ok(files.iter().map(|f| format!("{}\n", f.display())).collect());
    }
    let Some(field) = &a.field else {
        let files = if a.series.is_empty() {
            if a.x.is_some() {
                anyhow::bail!("--x needs the --series to draw against it");
            }
            crate::charts::run_sets(&a.runs, a.all, &a.output)?
        } else {
            crate::plot::compare(&a.runs, &a.series, a.x.as_deref(), &a.output)?
        };
        let mut s = String::new();
        for f in files {
            let _ = writeln!(s, "{}", f.display());
        }
        return Ok(s);
    };
    let choice = Choice::parse(field)?;
    let camera = a.view.camera()?;
    std::fs::create_dir_all(&a.output)
        .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", a.output.display()))?;
    let (mut drawn, mut named) = (Vec::new(), Vec::new());
    for run in &a.runs {
        let dir = folder_of(run);
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "run".into());
        let at_name = a.at.map(|t| format!("_{t:e}")).unwrap_or_default();
        let png = a.output.join(format!(
            "{name}_{}{at_name}.png",
            crate::plot::file_stem(field)
        ));
        let only = a.alone.then_some(choice.node);
        let t = fields::render(&dir, a.at, &png, Some(choice), only, camera)?.time;
        drawn.push((png, t));
        named.push((name, dir));
    }
    if named.len() > 1 {
        // the runs side by side on one colour range
        let at_name = a.at.map(|t| format!("_{t:e}")).unwrap_or_default();
        let png = a.output.join(format!(
            "runs_{}{at_name}.png",
            crate::plot::file_stem(field)
        ));
        let only = a.alone.then_some(choice.node);
        let drawn_runs = fields::render_runs(&named, a.at, &png, choice, only, camera)?;
        let latest = drawn_runs
            .iter()
            .map(|p| p.time)
            .fold(f64::NEG_INFINITY, f64::max);
        drawn.push((png, latest));
    }
    Ok(drawn_lines(&drawn))
}

/// `cosim params`: the models and their executables, or one model's parameters (a table,
/// or its JSON Schema with `--json`).
pub(super) fn params(a: &ParamsArgs) -> anyhow::Result<String> {
    let solver = a.solver.as_deref();
    let Some(m) = &a.model else {
        let all = crate::params::models(solver)?;
        if a.json {
            let v: Vec<serde_json::Value> = all
                .iter()
                .map(|(m, e)| serde_json::json!({ "model": m, "solver": e }))
                .collect();
            return Ok(serde_json::Value::Array(v).to_string());
        }
        let mut s = String::from("model               solver\n");
        for (m, e) in &all {
            s += &format!("{m:<20}{e}\n");
        }
        return Ok(s + "cosim params MODEL lists a model's parameters");
    };
    let (v, exe) = crate::params::schema(m, solver)?;
    if a.json {
        Ok(serde_json::to_string_pretty(&v)?)
    } else {
        Ok(crate::params::table(m, &exe, &crate::params::rows(&v)))
    }
}

/// A run folder stands for its recording (`cosim plot` takes either, so do `info` and
/// `replay`).
pub(super) fn recording_of(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.join("run.mcap")
    } else {
        path.to_path_buf()
    }
}

/// The folder of a run given as its folder or its recording.
pub(super) fn folder_of(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.to_path_buf()
    } else {
        path.parent().map(PathBuf::from).unwrap_or_default()
    }
}
