//! Field pictures (`fields.png`, `cosim render`): every node's VTK frame nearest a time, read
//! back from the run's `.pvd` series and drawn on one PNG — a gas grid as a colour map of its
//! pressure with the solids' particles over it (a plane view), or, without a grid, the solids'
//! deformed surfaces in an oblique view, shaded and coloured by plastic strain or stress, and
//! their particles coloured by damage (the joint's broken-bond fraction); one node alone, every
//! frame, or an animated GIF of the series; or several runs side by side on one colour range
//! (`cosim plot --field` of several runs). Reads what the nodes wrote (vtkio), so it works for
//! any node that writes VTK.

use anyhow::{Context, bail};
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use vtkio::model::{Attribute, CellType, DataSet, IOBuffer, Piece, VertexNumbers, Vtk};

/// A named array: components per entry and the values.
#[derive(Debug, Clone)]
struct Array {
    name: String,
    comps: usize,
    values: Vec<f64>,
}

/// One node's frame, reduced to what is drawn.
#[derive(Debug, Default)]
struct Frame {
    node: String,
    /// Rectilinear grid: cell edges per axis and cell arrays (x fastest).
    grid: Option<[Vec<f64>; 3]>,
    points: Vec<[f64; 3]>,
    /// Cells of 3 or more points (polygons); vertex cells are particles.
    polygons: Vec<Vec<usize>>,
    point_data: Vec<Array>,
    cell_data: Vec<Array>,
}

fn f64s(b: IOBuffer) -> Vec<f64> {
    b.cast_into::<f64>().unwrap_or_default()
}

fn arrays(attrs: Vec<Attribute>) -> Vec<Array> {
    attrs
        .into_iter()
        .filter_map(|a| match a {
            Attribute::DataArray(d) => Some(Array {
                comps: d.num_comp().max(1),
                name: d.name,
                values: f64s(d.data),
            }),
            Attribute::Field { .. } => None,
        })
        .collect()
}

fn inline<P>(pieces: Vec<Piece<P>>, file: &Path) -> anyhow::Result<P> {
    match pieces.into_iter().next() {
        Some(Piece::Inline(p)) => Ok(*p),
        _ => bail!("{}: no inline piece", file.display()),
    }
}

fn load(file: &Path, node: &str) -> anyhow::Result<Frame> {
    let vtk = Vtk::import(file).with_context(|| format!("cannot read {}", file.display()))?;
    let mut f = Frame {
        node: node.to_string(),
        ..Frame::default()
    };
    match vtk.data {
        DataSet::RectilinearGrid { pieces, .. } => {
            let p = inline(pieces, file)?;
            f.grid = Some([f64s(p.coords.x), f64s(p.coords.y), f64s(p.coords.z)]);
            f.cell_data = arrays(p.data.cell);
            f.point_data = arrays(p.data.point);
        }
        DataSet::UnstructuredGrid { pieces, .. } => {
            let p = inline(pieces, file)?;
            f.points = f64s(p.points)
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect();
            let (conn, offsets) = match p.cells.cell_verts {
                v @ VertexNumbers::Legacy { .. } => v.into_xml(),
                VertexNumbers::XML {
                    connectivity,
                    offsets,
                } => (connectivity, offsets),
            };
            let mut start = 0usize;
            for (k, &end) in offsets.iter().enumerate() {
                let end = end as usize;
                let ids: Vec<usize> = conn
                    .get(start..end)
                    .unwrap_or_default()
                    .iter()
                    .map(|&i| i as usize)
                    .filter(|&i| i < f.points.len())
                    .collect();
                let kind = p.cells.types.get(k).copied();
                if ids.len() >= 3 && kind != Some(CellType::PolyVertex) {
                    f.polygons.push(ids);
                }
                start = end;
            }
            f.cell_data = arrays(p.data.cell);
            f.point_data = arrays(p.data.point);
        }
        _ => bail!("{}: not a rectilinear or unstructured grid", file.display()),
    }
    Ok(f)
}

/// The `(time, file)` entries of a `.pvd` series (read by the nodes' own writer's reader).
fn series(pvd: &Path) -> anyhow::Result<Vec<(f64, PathBuf)>> {
    let dir = pvd.parent().unwrap_or(Path::new("."));
    let stem = pvd
        .file_stem()
        .and_then(|s| s.to_str())
        .with_context(|| format!("{}: not a series name", pvd.display()))?;
    let entries = node_kit::vtk::series(dir, stem)
        .with_context(|| format!("cannot read {}", pvd.display()))?;
    Ok(entries
        .into_iter()
        .map(|e| (e.time, dir.join(e.file)))
        .collect())
}

/// Every `.pvd` series of the run: `(node folder, series)`, in name order.
fn all_series(run: &Path) -> Vec<(String, PathBuf)> {
    let mut out = Vec::new();
    let Ok(rd) = std::fs::read_dir(run) else {
        return out;
    };
    let mut dirs: Vec<PathBuf> = rd
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_dir())
        .collect();
    dirs.sort();
    for d in dirs {
        let Ok(rd) = std::fs::read_dir(&d) else {
            continue;
        };
        let mut pvds: Vec<PathBuf> = rd
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|e| e == "pvd"))
            .collect();
        pvds.sort();
        let node = d
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        out.extend(pvds.into_iter().map(|p| (node.clone(), p)));
    }
    out
}

/// Whether any node of the run wrote a VTK series.
pub fn has_series(run: &Path) -> bool {
    !all_series(run).is_empty()
}

/// The colour map of a field: viridis for a field of one sign, ParaView's "Cool to Warm"
/// (blue–grey–red) centred on zero for a signed one, grey for the background field under
/// another one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Map {
    Viridis,
    Diverging,
    Grey,
    /// White to red: a damage fraction over the gas.
    WhiteRed,
}

/// One field's colour scale as drawn: its caption (node, field, the measure drawn of a vector
/// or tensor, unit), its range and its map.
#[derive(Debug, Clone)]
pub struct Scale {
    pub label: String,
    pub lo: f64,
    pub hi: f64,
    pub map: Map,
}

impl Scale {
    /// A scale over `lo..hi`: diverging and symmetric about zero where the values take both
    /// signs, else viridis (`grey` for a background field).
    fn new(label: String, (lo, hi): (f64, f64), grey: bool) -> Scale {
        if grey {
            return Scale {
                label,
                lo,
                hi,
                map: Map::Grey,
            };
        }
        if lo < 0.0 && hi > 0.0 {
            let m = lo.abs().max(hi);
            return Scale {
                label,
                lo: -m,
                hi: m,
                map: Map::Diverging,
            };
        }
        Scale {
            label,
            lo,
            hi,
            map: Map::Viridis,
        }
    }

    /// The colour of value `v`.
    fn colour(&self, v: f64) -> RGBColor {
        self.at((v - self.lo) / (self.hi - self.lo))
    }

    /// The colour at `s` of the way up the scale (0..1).
    fn at(&self, s: f64) -> RGBColor {
        let s = if s.is_finite() {
            s.clamp(0.0, 1.0)
        } else {
            0.0
        };
        match self.map {
            Map::Viridis => colour(s),
            Map::Grey => {
                let g = (70.0 + 170.0 * s).round() as u8;
                RGBColor(g, g, g)
            }
            Map::WhiteRed => {
                let g = (235.0 * (1.0 - s)) as u8;
                RGBColor(235, g, g)
            }
            Map::Diverging => cool_to_warm(s),
        }
    }
}

/// What a picture shows: the time drawn, the colour scale of each field drawn (one colour bar
/// each) and the length of its scale bar.
#[derive(Debug, Clone)]
pub struct Picture {
    pub time: f64,
    pub scales: Vec<Scale>,
    pub length_scale: Option<String>,
}

/// ParaView's default map, "Cool to Warm": Moreland's diverging map from blue (59, 76, 192)
/// through a neutral grey to red (180, 4, 38), interpolated in his Msh space (polar CIELAB:
/// magnitude, saturation, hue), so that lightness rises evenly to the middle and falls evenly
/// after it (K. Moreland, "Diverging color maps for scientific visualization", ISVC 2009).
/// Read from a table of 1,025 colours made once: the Msh interpolation costs about half a
/// microsecond a colour (measured), so about 0.09 s for the 160,000 cells of a 400² grid and
/// seconds for a GPU-sized one.
fn cool_to_warm(s: f64) -> RGBColor {
    const N: usize = 1024;
    static TABLE: std::sync::OnceLock<Vec<RGBColor>> = std::sync::OnceLock::new();
    let t = TABLE.get_or_init(|| {
        (0..=N)
            .map(|k| cool_to_warm_msh(k as f64 / N as f64))
            .collect()
    });
    let s = if s.is_finite() {
        s.clamp(0.0, 1.0)
    } else {
        0.0
    };
    t[(s * N as f64).round() as usize]
}

/// [`cool_to_warm`] computed: Moreland's interpolation in Msh.
fn cool_to_warm_msh(s: f64) -> RGBColor {
    const COOL: [f64; 3] = [59.0, 76.0, 192.0];
    const WARM: [f64; 3] = [180.0, 4.0, 38.0];
    let (mut a, mut b) = (msh(COOL), msh(WARM));
    // Two saturated ends of distant hues pass through an unsaturated middle, at least as
    // light as either end and as L* = 88.
    let mid = a[0].max(b[0]).max(88.0);
    let t = if s < 0.5 {
        b = [mid, 0.0, 0.0];
        2.0 * s
    } else {
        a = [mid, 0.0, 0.0];
        2.0 * s - 1.0
    };
    // The unsaturated middle takes the hue of the saturated end, turned so that the hue
    // does not jump where the saturation leaves zero.
    let spin = |sat: [f64; 3], m_unsat: f64| {
        let [m, sa, h] = sat;
        if m >= m_unsat - 0.1 {
            return h;
        }
        let turn = sa * (m_unsat * m_unsat - m * m).sqrt() / (m * sa.sin());
        if h > -std::f64::consts::FRAC_PI_3 {
            h + turn
        } else {
            h - turn
        }
    };
    if a[1] < 0.05 && b[1] > 0.05 {
        a[2] = spin(b, a[0]);
    } else if b[1] < 0.05 && a[1] > 0.05 {
        b[2] = spin(a, b[0]);
    }
    let m: [f64; 3] = std::array::from_fn(|i| a[i] + t * (b[i] - a[i]));
    let c = rgb_of_msh(m);
    let byte = |x: f64| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
    RGBColor(byte(c[0]), byte(c[1]), byte(c[2]))
}

/// CIELAB's reference white (D65, as Moreland's map uses it).
const D65_WHITE: [f64; 3] = [0.9505, 1.0, 1.089];

/// An sRGB colour (0–255) in Msh: magnitude, saturation (angle from the grey axis) and hue.
fn msh(rgb: [f64; 3]) -> [f64; 3] {
    let lin: [f64; 3] = std::array::from_fn(|i| {
        let c = rgb[i] / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    });
    let xyz = [
        0.4124 * lin[0] + 0.3576 * lin[1] + 0.1805 * lin[2],
        0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2],
        0.0193 * lin[0] + 0.1192 * lin[1] + 0.9505 * lin[2],
    ];
    let f: [f64; 3] = std::array::from_fn(|i| {
        let t = xyz[i] / D65_WHITE[i];
        if t > 0.008856 {
            t.cbrt()
        } else {
            7.787 * t + 16.0 / 116.0
        }
    });
    let (l, a, b) = (
        116.0 * f[1] - 16.0,
        500.0 * (f[0] - f[1]),
        200.0 * (f[1] - f[2]),
    );
    let m = (l * l + a * a + b * b).sqrt();
    [m, (l / m).acos(), b.atan2(a)]
}

/// The inverse of [`msh`], as linear-light-corrected sRGB in 0–1 (not clamped).
fn rgb_of_msh([m, s, h]: [f64; 3]) -> [f64; 3] {
    let (l, a, b) = (m * s.cos(), m * s.sin() * h.cos(), m * s.sin() * h.sin());
    let fy = (l + 16.0) / 116.0;
    let f = [fy + a / 500.0, fy, fy - b / 200.0];
    let xyz: [f64; 3] = std::array::from_fn(|i| {
        let t = if f[i] > 0.20689 {
            f[i].powi(3)
        } else {
            (f[i] - 16.0 / 116.0) / 7.787
        };
        t * D65_WHITE[i]
    });
    let lin = [
        3.2406 * xyz[0] - 1.5372 * xyz[1] - 0.4986 * xyz[2],
        -0.9689 * xyz[0] + 1.8758 * xyz[1] + 0.0415 * xyz[2],
        0.0557 * xyz[0] - 0.2040 * xyz[1] + 1.0570 * xyz[2],
    ];
    std::array::from_fn(|i| {
        let c = lin[i];
        if c <= 0.0031308 {
            12.92 * c
        } else {
            1.055 * c.powf(1.0 / 2.4) - 0.055
        }
    })
}

/// A colour map from dark blue through green to yellow (viridis, 6 stops).
fn colour(s: f64) -> RGBColor {
    const STOPS: [(f64, f64, f64); 6] = [
        (68.0, 1.0, 84.0),
        (65.0, 68.0, 135.0),
        (42.0, 120.0, 142.0),
        (34.0, 168.0, 132.0),
        (122.0, 209.0, 81.0),
        (253.0, 231.0, 37.0),
    ];
    let s = if s.is_finite() {
        s.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = s * (STOPS.len() - 1) as f64;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let w = x - i as f64;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    let mix = |p: f64, q: f64| (p + w * (q - p)).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

fn shade(c: RGBColor, k: f64) -> RGBColor {
    let f = |v: u8| (v as f64 * k).round().clamp(0.0, 255.0) as u8;
    RGBColor(f(c.0), f(c.1), f(c.2))
}

/// Whether an array is a stress tensor: [σxx, σyy, σxy] in 2-D, six (Voigt) or nine
/// components in 3-D.
fn is_stress(a: &Array) -> bool {
    a.name.contains("stress") && matches!(a.comps, 3 | 6 | 9)
}

/// The measure drawn of an array's entries: None for a scalar, "von Mises" for a stress
/// tensor (in-plane for three components), "magnitude" for a vector.
fn measure(a: &Array) -> Option<&'static str> {
    match a.comps {
        1 => None,
        3 if is_stress(a) => Some("von Mises, in-plane"),
        _ if is_stress(a) => Some("von Mises"),
        _ => Some("magnitude"),
    }
}

/// Entry `i` as one number: the value itself, the von Mises stress of a stress tensor, else
/// a vector's magnitude.
fn magnitude(a: &Array, i: usize) -> f64 {
    let v = &a.values[i * a.comps..(i + 1) * a.comps];
    let mises = |n: [f64; 3], s: [f64; 3]| {
        (0.5 * ((n[0] - n[1]).powi(2) + (n[1] - n[2]).powi(2) + (n[2] - n[0]).powi(2))
            + 3.0 * (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]))
            .sqrt()
    };
    match (a.comps, is_stress(a)) {
        (1, _) => v[0],
        (3, true) => mises([v[0], v[1], 0.0], [v[2], 0.0, 0.0]),
        (6, true) => mises([v[0], v[1], v[2]], [v[3], v[4], v[5]]),
        (9, true) => mises(
            [v[0], v[4], v[8]],
            [
                0.5 * (v[1] + v[3]),
                0.5 * (v[5] + v[7]),
                0.5 * (v[2] + v[6]),
            ],
        ),
        _ => v.iter().map(|x| x * x).sum::<f64>().sqrt(),
    }
}

/// Whether the entries of `a` (as drawn) take more than one value.
fn varies(a: &Array) -> bool {
    let n = a.values.len() / a.comps.max(1);
    let first = (0..n).map(|i| magnitude(a, i)).find(|v| v.is_finite());
    first.is_some_and(|f| (0..n).any(|i| magnitude(a, i) != f && magnitude(a, i).is_finite()))
}

/// The first of `names` that `list` holds with `n` entries that vary (a field of one value,
/// such as the damage of a model without damage, shows nothing).
fn pick<'a>(list: &'a [Array], names: &[&str], n: usize) -> Option<&'a Array> {
    names
        .iter()
        .find_map(|want| pick_sized(list, &[want], n).filter(|a| varies(a)))
}

/// Of `names`, the field of `list` (with `n` entries) that shows most: the largest ratio of
/// its largest to its smallest value for a positive field (a shock's pressure, a bubble's
/// density), else of its span to its largest magnitude.
fn pick_most<'a>(list: &'a [Array], names: &[&str], n: usize) -> Option<&'a Array> {
    let contrast = |a: &Array| {
        let (lo, hi) = range((0..n).map(|i| magnitude(a, i)));
        if lo > 0.0 {
            hi / lo
        } else {
            1.0 + (hi - lo) / lo.abs().max(hi.abs()).max(1e-300)
        }
    };
    names
        .iter()
        .filter_map(|want| pick(list, &[want], n))
        .max_by(|a, b| contrast(a).total_cmp(&contrast(b)))
}

/// The first of `names` that `list` holds with `n` entries, zero or not.
fn pick_sized<'a>(list: &'a [Array], names: &[&str], n: usize) -> Option<&'a Array> {
    names.iter().find_map(|want| {
        list.iter()
            .find(|a| a.name == *want && a.values.len() == a.comps * n)
    })
}

fn range(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = v
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    if lo.is_finite() && hi > lo {
        (lo, hi)
    } else if lo.is_finite() {
        (lo, lo + 1.0)
    } else {
        (0.0, 1.0)
    }
}

/// A linear map from a box of the model onto the picture, keeping the aspect ratio.
struct View {
    lo: [f64; 2],
    scale: f64,
    origin: (i32, i32),
    height: i32,
}

impl View {
    fn fit(lo: [f64; 2], hi: [f64; 2], area: (i32, i32, i32, i32)) -> View {
        let (x0, y0, w, h) = area;
        let sx = w as f64 / (hi[0] - lo[0]).max(1e-300);
        let sy = h as f64 / (hi[1] - lo[1]).max(1e-300);
        let scale = sx.min(sy);
        let used = ((hi[0] - lo[0]) * scale, (hi[1] - lo[1]) * scale);
        View {
            lo,
            scale,
            origin: (
                x0 + ((w as f64 - used.0) / 2.0) as i32,
                y0 + ((h as f64 - used.1) / 2.0) as i32,
            ),
            height: used.1.round() as i32,
        }
    }
    fn px(&self, x: f64, y: f64) -> (i32, i32) {
        (
            self.origin.0 + ((x - self.lo[0]) * self.scale).round() as i32,
            self.origin.1 + self.height - ((y - self.lo[1]) * self.scale).round() as i32,
        )
    }
}

const SIZE: (u32, u32) = (1200, 800);
const PLOT: (i32, i32, i32, i32) = (40, 60, 1000, 700);

/// How the oblique view looks at the solids: which axis points up and the view's turn and
/// tilt. `Camera::default()` is automatic: the longest axis of the bodies across, the second
/// up, turned 30° and tilted 20° (a flat body face on).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// The axis drawn upwards (0 x, 1 y, 2 z); the next axis in the cycle x → y → z → x is
    /// drawn across and the third is the depth. None: chosen from the bodies' extents.
    pub up: Option<usize>,
    /// Turn about the up axis, degrees (0: looking along the depth axis, a side view).
    pub yaw: f64,
    /// Tilt, degrees (positive: looking down on the bodies).
    pub pitch: f64,
}

impl Default for Camera {
    fn default() -> Self {
        Camera {
            up: None,
            yaw: 30.0,
            pitch: 20.0,
        }
    }
}

impl Camera {
    /// The camera of `cosim render --up AXIS --yaw DEG --pitch DEG` (each optional).
    pub fn from_args(
        up: Option<&str>,
        yaw: Option<f64>,
        pitch: Option<f64>,
    ) -> anyhow::Result<Self> {
        let d = Camera::default();
        let up = match up {
            None => None,
            Some("x") => Some(0),
            Some("y") => Some(1),
            Some("z") => Some(2),
            Some(o) => anyhow::bail!("--up {o}: must be x, y or z"),
        };
        for (name, v) in [("--yaw", yaw), ("--pitch", pitch)] {
            if let Some(v) = v
                && !(v.is_finite() && (-180.0..=180.0).contains(&v))
            {
                anyhow::bail!("{name} {v}: must be an angle in degrees, -180 to 180");
            }
        }
        Ok(Camera {
            up,
            yaw: yaw.unwrap_or(d.yaw),
            pitch: pitch.unwrap_or(d.pitch),
        })
    }
}

/// A field chosen to colour one node's frame (`cosim plot RUN --field NODE.FIELD`): a cell
/// or point array of its VTK frames, drawn by magnitude.
#[derive(Debug, Clone, Copy)]
pub struct Choice<'a> {
    pub node: &'a str,
    pub field: &'a str,
    /// The colour range, where several pictures share one (`cosim plot --field` of several
    /// runs side by side); None: the range of the values drawn.
    pub span: Option<(f64, f64)>,
}

impl<'a> Choice<'a> {
    /// `NODE.FIELD` (the field name may itself hold dots).
    pub fn parse(spec: &'a str) -> anyhow::Result<Self> {
        match spec.split_once('.') {
            Some((node, field)) if !node.is_empty() && !field.is_empty() => Ok(Choice {
                node,
                field,
                span: None,
            }),
            _ => bail!("--field {spec}: must be NODE.FIELD, e.g. gas.density or bar.damage"),
        }
    }
}

/// The names to colour frame `f` by: the chosen field for the chosen node, else `default`.
fn wanted<'a>(f: &Frame, choice: Option<Choice<'a>>, default: &[&'a str]) -> Vec<&'a str> {
    match choice {
        Some(c) if c.node == f.node => vec![c.field],
        _ => default.to_vec(),
    }
}

/// A colour-bar caption of array `a` of `node`: `node: field (measure) [unit]`.
fn caption(node: &str, a: &Array) -> String {
    label(node, &a.name, measure(a))
}

/// `who: field (measure) [unit]`.
fn label(who: &str, field: &str, measure: Option<&str>) -> String {
    let m = measure.map(|m| format!(" ({m})")).unwrap_or_default();
    match crate::plot::unit_of(field) {
        Some(u) => format!("{who}: {field}{m} [{u}]"),
        None => format!("{who}: {field}{m}"),
    }
}

/// Refuses a choice whose node or field the frames do not hold, listing what they hold.
fn check_choice(frames: &[Frame], c: Choice) -> anyhow::Result<()> {
    let Some(f) = frames.iter().find(|f| f.node == c.node) else {
        let nodes: Vec<&str> = frames.iter().map(|f| f.node.as_str()).collect();
        bail!(
            "--field {}.{}: no VTK frames of node '{}' (nodes with frames: {nodes:?})",
            c.node,
            c.field,
            c.node
        );
    };
    let names: Vec<&str> = f
        .cell_data
        .iter()
        .chain(&f.point_data)
        .map(|a| a.name.as_str())
        .collect();
    if !names.contains(&c.field) {
        bail!(
            "--field {}.{}: node '{}' writes no field '{}' (it writes {names:?})",
            c.node,
            c.field,
            c.node,
            c.field
        );
    }
    Ok(())
}

/// The frames nearest `time` (the last ones when None) of every node of the run, or of `node`
/// alone, and the latest time among them.
fn frames_at(
    run_dir: &Path,
    time: Option<f64>,
    node: Option<&str>,
) -> anyhow::Result<(Vec<Frame>, f64)> {
    let mut frames = Vec::new();
    let mut t_drawn = f64::NEG_INFINITY;
    for (name, pvd) in all_series(run_dir) {
        if node.is_some_and(|n| n != name) {
            continue;
        }
        let s = series(&pvd)?;
        let pick = match time {
            None => s.last(),
            Some(t) => s
                .iter()
                .min_by(|a, b| (a.0 - t).abs().total_cmp(&(b.0 - t).abs())),
        };
        if let Some((t, file)) = pick {
            frames.push(load(file, &name)?);
            t_drawn = t_drawn.max(*t);
        }
    }
    if frames.is_empty() {
        match node {
            Some(n) => bail!(
                "{}: node '{n}' wrote no VTK series (nodes with series: {:?})",
                run_dir.display(),
                nodes_with_series(run_dir)
            ),
            None => bail!(
                "{}: no VTK series (.pvd) in its node folders",
                run_dir.display()
            ),
        }
    }
    Ok((frames, t_drawn))
}

/// The nodes of the run that wrote a VTK series, in name order, each once.
pub fn nodes_with_series(run_dir: &Path) -> Vec<String> {
    let mut nodes: Vec<String> = all_series(run_dir).into_iter().map(|(n, _)| n).collect();
    nodes.dedup();
    nodes
}

/// Draws `frames` (time `t`) on `root`: the plane view when a gas grid is among them, else
/// the oblique view; a colour bar per field drawn, a length scale and the caption. Returns
/// what it drew.
fn draw(
    root: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    frames: &[Frame],
    choice: Option<Choice>,
    camera: Camera,
    t: f64,
    title: &str,
) -> anyhow::Result<Picture> {
    let text = crate::plot::font_ready();
    root.fill(&WHITE)?;
    let (scales, px_per_m) = if frames.iter().any(|f| f.grid.is_some()) {
        plane_view(root, frames, choice)?
    } else {
        oblique_view(root, frames, choice, camera)?
    };
    for (k, sc) in scales.iter().enumerate() {
        colour_bar(root, sc, k, scales.len(), text)?;
    }
    let length_scale = scale_bar(root, px_per_m, text)?;
    if text {
        let mut names: Vec<&str> = Vec::new();
        for f in frames {
            if !names.contains(&f.node.as_str()) {
                names.push(&f.node);
            }
        }
        root.draw(&Text::new(
            format!("{title}t = {t:.4e} s   nodes: {}", names.join(", ")),
            (40, 20),
            ("sans-serif", 22).into_font(),
        ))?;
    }
    Ok(Picture {
        time: t,
        scales,
        length_scale,
    })
}

/// Draws the frames nearest `time` (the last ones when None) of the run in `run_dir` — of
/// every node, or of `node` alone — into `png`, one node coloured by a chosen field if
/// `choice` says so; returns what it drew (the time: the latest of the frames used).
pub fn render(
    run_dir: &Path,
    time: Option<f64>,
    png: &Path,
    choice: Option<Choice>,
    node: Option<&str>,
    camera: Camera,
) -> anyhow::Result<Picture> {
    let (frames, t_drawn) = frames_at(run_dir, time, node)?;
    if let Some(c) = choice {
        check_choice(&frames, c)?;
    }
    crate::plot::png_whole(png, |tmp| {
        let root = BitMapBackend::new(tmp, SIZE).into_drawing_area();
        let picture = draw(&root, &frames, choice, camera, t_drawn, "")?;
        root.present()?;
        Ok(picture)
    })
}

/// The chosen field's frames nearest `time` in each of `runs` (name, folder) side by side in
/// one PNG — a row of up to three, else a near-square grid, each panel captioned with its run's name — on one colour
/// range, the union of the values of every run, so that the panels compare by colour; every
/// node of each run, or `node` alone. Returns what each panel drew.
pub fn render_runs(
    runs: &[(String, PathBuf)],
    time: Option<f64>,
    png: &Path,
    choice: Choice,
    node: Option<&str>,
    camera: Camera,
) -> anyhow::Result<Vec<Picture>> {
    let mut all = Vec::new();
    let mut span = (f64::INFINITY, f64::NEG_INFINITY);
    for (name, dir) in runs {
        let (frames, t) = frames_at(dir, time, node)?;
        check_choice(&frames, choice).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
        for f in frames.iter().filter(|f| f.node == choice.node) {
            // a grid's field is cell data; a solid's is point data (particles) or cell data
            // (a shell's plastic strain)
            let found = if f.grid.is_some() {
                f.cell_data.iter().find(|a| a.name == choice.field)
            } else {
                f.point_data
                    .iter()
                    .chain(&f.cell_data)
                    .find(|a| a.name == choice.field)
            };
            if let Some(a) = found {
                let (lo, hi) = range((0..a.values.len() / a.comps.max(1)).map(|i| magnitude(a, i)));
                span = (span.0.min(lo), span.1.max(hi));
            }
        }
        all.push((name, frames, t));
    }
    let shared = Choice {
        span: span.0.is_finite().then_some(span),
        ..choice
    };
    // a row of up to three, else a near-square grid
    let n = all.len().max(1);
    let cols = if n <= 3 {
        n
    } else {
        n.isqrt() + usize::from(n.isqrt().pow(2) < n)
    };
    let rows = all.len().div_ceil(cols);
    let size = (SIZE.0 * cols as u32, SIZE.1 * rows as u32);
    crate::plot::png_whole(png, |tmp| {
        let root = BitMapBackend::new(tmp, size).into_drawing_area();
        root.fill(&WHITE)?;
        let panels = root.split_evenly((rows, cols));
        let mut drawn = Vec::new();
        for ((name, frames, t), area) in all.iter().zip(&panels) {
            drawn.push(draw(
                area,
                frames,
                Some(shared),
                camera,
                *t,
                &format!("{name}:   "),
            )?);
        }
        root.present()?;
        Ok(drawn)
    })
}

/// A run of more nodes than this draws only the picture of all of them when it ends (a crash
/// tube's ten joints; `cosim render RUN --per-node` draws each).
pub const MAX_NODE_PICTURES: usize = 4;

/// The last frame of each node alone into `RUN/fields_<node>.png`, where two to
/// [`MAX_NODE_PICTURES`] nodes wrote a series (one node's picture is `fields.png` itself);
/// returns the files.
pub fn render_nodes(run_dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let nodes = nodes_with_series(run_dir);
    if nodes.len() < 2 || nodes.len() > MAX_NODE_PICTURES {
        return Ok(Vec::new());
    }
    let mut files = Vec::with_capacity(nodes.len());
    for n in &nodes {
        let png = run_dir.join(format!("fields_{n}.png"));
        render(run_dir, None, &png, None, Some(n), Camera::default())?;
        files.push(png);
    }
    Ok(files)
}

/// Every written time of the run (the union of the frame times of every node, or of `node`),
/// in order, times equal to 1e-12 relative counted once.
fn frame_times(run_dir: &Path, node: Option<&str>) -> anyhow::Result<Vec<f64>> {
    let mut times: Vec<f64> = Vec::new();
    for (name, pvd) in all_series(run_dir) {
        if node.is_none_or(|n| n == name) {
            times.extend(series(&pvd)?.into_iter().map(|(t, _)| t));
        }
    }
    times.sort_by(f64::total_cmp);
    times.dedup_by(|a, b| (*a - *b).abs() <= 1e-12 * a.abs().max(b.abs()));
    if times.is_empty() {
        bail!(
            "{}: no VTK series (.pvd) in its node folders{}",
            run_dir.display(),
            node.map(|n| format!(" for node '{n}'")).unwrap_or_default()
        );
    }
    Ok(times)
}

/// `cosim render --all`: one picture per written time into `RUN/frames/fields_<k>.png` (with
/// `node`, that node's frames alone into `RUN/frames/<node>_<k>.png`), k counting from 0;
/// returns each file and its time.
pub fn render_all(
    run_dir: &Path,
    choice: Option<Choice>,
    node: Option<&str>,
    camera: Camera,
) -> anyhow::Result<Vec<(PathBuf, f64)>> {
    let times = frame_times(run_dir, node)?;
    let dir = run_dir.join("frames");
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut out = Vec::with_capacity(times.len());
    for (k, t) in times.into_iter().enumerate() {
        let png = dir.join(format!("{}_{k:04}.png", node.unwrap_or("fields")));
        let drawn = render(run_dir, Some(t), &png, choice, node, camera)?;
        out.push((png, drawn.time));
    }
    Ok(out)
}

/// `cosim render --gif`: every written time as one frame of an animated GIF (`delay_ms` per
/// frame), of every node or of `node` alone; returns the number of frames and the last time.
pub fn render_gif(
    run_dir: &Path,
    gif: &Path,
    choice: Option<Choice>,
    node: Option<&str>,
    delay_ms: u32,
    camera: Camera,
) -> anyhow::Result<(usize, f64)> {
    let times = frame_times(run_dir, node)?;
    if let Some(parent) = gif.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create {}", parent.display()))?;
    }
    let root = BitMapBackend::gif(gif, SIZE, delay_ms)
        .with_context(|| format!("cannot create {}", gif.display()))?
        .into_drawing_area();
    let mut last = 0.0;
    for &t in &times {
        let (frames, drawn) = frames_at(run_dir, Some(t), node)?;
        if let Some(c) = choice {
            check_choice(&frames, c)?;
        }
        draw(&root, &frames, choice, camera, drawn, "")?;
        root.present()
            .with_context(|| format!("cannot write {}", gif.display()))?;
        last = drawn;
    }
    Ok((times.len(), last))
}

/// The gas grid's x–y plane (its middle z layer) coloured by the field that shows most, the
/// solids' particles and surfaces projected on it; a solid's chosen field takes a colour bar
/// of its own and the gas goes grey under it. Returns the scales and pixels per metre.
fn plane_view(
    root: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    frames: &[Frame],
    choice: Option<Choice>,
) -> anyhow::Result<(Vec<Scale>, f64)> {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for f in frames {
        if let Some(g) = &f.grid {
            for d in 0..2 {
                lo[d] = lo[d].min(g[d][0]);
                hi[d] = hi[d].max(*g[d].last().unwrap_or(&g[d][0]));
            }
        }
    }
    let view = View::fit(lo, hi, PLOT);
    let over = choice.is_some_and(|c| frames.iter().any(|f| f.grid.is_none() && f.node == c.node));
    let mut scales = Vec::new();
    for f in frames {
        scales.extend(draw_grid_layer(root, f, choice, &view, over)?);
    }
    for f in frames.iter().filter(|f| f.grid.is_none()) {
        scales.extend(draw_solid_flat(root, f, choice, &view)?);
    }
    Ok((scales, view.scale))
}

/// The middle z layer of frame `f`'s grid, its cells coloured by the chosen field, else by
/// pressure or density, whichever shows more (grey when `under` another field): its scale,
/// or None where the frame has no grid or no such field.
fn draw_grid_layer(
    root: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    f: &Frame,
    choice: Option<Choice>,
    view: &View,
    under: bool,
) -> anyhow::Result<Option<Scale>> {
    let Some(g) = &f.grid else { return Ok(None) };
    let n = [g[0].len() - 1, g[1].len() - 1, g[2].len().max(2) - 1];
    let cells = n[0] * n[1] * n[2];
    // a chosen field is drawn even where it is uniform; the default is the one that shows
    let chosen = choice.filter(|c| c.node == f.node);
    let Some(a) = (match chosen {
        Some(c) => pick_sized(&f.cell_data, &[c.field], cells),
        None => pick_most(&f.cell_data, &["pressure", "density"], cells),
    }) else {
        return Ok(None);
    };
    let k = n[2] / 2;
    let layer = |i: usize, j: usize| magnitude(a, i + n[0] * (j + n[1] * k));
    let span = chosen.and_then(|c| c.span).unwrap_or_else(|| {
        range(
            (0..n[1])
                .flat_map(|j| (0..n[0]).map(move |i| (i, j)))
                .map(|(i, j)| layer(i, j)),
        )
    });
    let sc = Scale::new(caption(&f.node, a), span, under);
    for j in 0..n[1] {
        for i in 0..n[0] {
            let c = sc.colour(layer(i, j));
            let (x0, y1) = view.px(g[0][i], g[1][j]);
            let (x1, y0) = view.px(g[0][i + 1], g[1][j + 1]);
            root.draw(&Rectangle::new([(x0, y0), (x1, y1)], c.filled()))?;
        }
    }
    Ok(Some(sc))
}

/// A solid frame `f` over the grid seen from above: its particles coloured by a chosen point
/// field (which takes a colour bar), else shaded by damage; a mesh as grey polygons.
fn draw_solid_flat(
    root: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    f: &Frame,
    choice: Option<Choice>,
    view: &View,
) -> anyhow::Result<Option<Scale>> {
    let mine = choice.filter(|c| c.node == f.node);
    let chosen = mine.and_then(|c| pick_sized(&f.point_data, &[c.field], f.points.len()));
    let r = if f.points.len() > 20_000 { 1 } else { 2 };
    if let Some(a) = chosen {
        let span = mine.and_then(|c| c.span);
        let span = span.unwrap_or_else(|| range((0..f.points.len()).map(|i| magnitude(a, i))));
        let sc = Scale::new(caption(&f.node, a), span, false);
        for (i, p) in f.points.iter().enumerate() {
            let c = sc.colour(magnitude(a, i));
            root.draw(&Circle::new(view.px(p[0], p[1]), r, c.filled()))?;
        }
        return Ok(Some(sc));
    }
    if f.polygons.is_empty() {
        // white to red by damage on 0..1 (its own bar where there is damage)
        let damage = pick(&f.point_data, &["damage"], f.points.len());
        let sc = Scale {
            label: damage.map_or(String::new(), |a| caption(&f.node, a)),
            lo: 0.0,
            hi: 1.0,
            map: Map::WhiteRed,
        };
        for (i, p) in f.points.iter().enumerate() {
            let c = sc.colour(damage.map_or(0.0, |a| magnitude(a, i)));
            root.draw(&Circle::new(view.px(p[0], p[1]), r, c.filled()))?;
        }
        if damage.is_some() {
            return Ok(Some(sc));
        }
    } else {
        for poly in &f.polygons {
            let pts: Vec<(i32, i32)> = poly
                .iter()
                .map(|&i| view.px(f.points[i][0], f.points[i][1]))
                .collect();
            root.draw(&Polygon::new(pts, RGBColor(90, 90, 90).filled()))?;
        }
    }
    Ok(None)
}

/// The solids' surfaces in an oblique view (longest axis across, second longest up, turned
/// 30° and tilted 20°), shaded by their facing and coloured by plastic strain, else stress,
/// else displacement; particles as dots.
fn oblique_view(
    root: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    frames: &[Frame],
    choice: Option<Choice>,
    look: Camera,
) -> anyhow::Result<(Vec<Scale>, f64)> {
    let camera = Oblique::of(frames, look);
    let mut plo = [f64::INFINITY; 2];
    let mut phi = [f64::NEG_INFINITY; 2];
    for p in frames.iter().flat_map(|f| f.points.iter()) {
        let q = camera.project(p);
        for d in 0..2 {
            plo[d] = plo[d].min(q[d]);
            phi[d] = phi[d].max(q[d]);
        }
    }
    let view = View::fit(plo, phi, PLOT);
    let (faces, surface) = surfaces(frames, choice, &camera);
    let (fields, shared) = particle_fields(frames, choice);
    let mut particle_scales = particle_scales(&shared);
    // A node whose surfaces and particles show the same field (hexahedra around an SPG
    // core) gets one scale over both, drawn once.
    let mut surface = surface;
    if let Some(sc) = &mut surface
        && let Some(k) = particle_scales.iter().position(|p| p.label == sc.label)
    {
        let p = particle_scales.remove(k);
        let span = (sc.lo.min(p.lo), sc.hi.max(p.hi));
        *sc = Scale::new(sc.label.clone(), span, false);
        particle_scales.insert(k, sc.clone());
    }
    paint_surfaces(root, faces, surface.as_ref(), &view)?;
    paint_particles(root, &fields, &shared, &particle_scales, &camera, &view)?;
    let mut scales: Vec<Scale> = surface.into_iter().collect();
    for sc in particle_scales {
        if !scales.iter().any(|s| s.label == sc.label) {
            scales.push(sc);
        }
    }
    Ok((scales, view.scale))
}

/// The oblique camera over a set of frames: their bounding box's axes by length, its centre,
/// and the turn and tilt.
struct Oblique {
    axes: [usize; 3],
    centre: [f64; 3],
    yaw: f64,
    pitch: f64,
}

impl Oblique {
    fn of(frames: &[Frame], camera: Camera) -> Oblique {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in frames.iter().flat_map(|f| f.points.iter()) {
            for d in 0..3 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        let (axes, yaw, pitch) = if let Some(up) = camera.up {
            ([(up + 1) % 3, up, (up + 2) % 3], camera.yaw, camera.pitch)
        } else {
            let mut axes = [0usize, 1, 2];
            axes.sort_by(|&a, &b| (hi[b] - lo[b]).total_cmp(&(hi[a] - lo[a])));
            // a flat body (a 2-D model's particles or mesh) is seen face on
            let flat = hi[axes[2]] - lo[axes[2]] <= 1e-9 * (hi[axes[0]] - lo[axes[0]]);
            if flat {
                (axes, 0.0, 0.0)
            } else {
                (axes, camera.yaw, camera.pitch)
            }
        };
        let (yaw, pitch) = (yaw.to_radians(), pitch.to_radians());
        Oblique {
            axes,
            centre: std::array::from_fn(|d| 0.5 * (lo[d] + hi[d])),
            yaw,
            pitch,
        }
    }

    /// A point on the picture plane (x, y) and its depth.
    fn project(&self, p: &[f64; 3]) -> [f64; 3] {
        let (axes, centre) = (&self.axes, &self.centre);
        let (a, b, c) = (
            p[axes[0]] - centre[axes[0]],
            p[axes[1]] - centre[axes[1]],
            p[axes[2]] - centre[axes[2]],
        );
        let (yaw, pitch) = (self.yaw, self.pitch);
        let x = a * yaw.cos() + c * yaw.sin();
        let z1 = -a * yaw.sin() + c * yaw.cos();
        let y = b * pitch.cos() - z1 * pitch.sin();
        let depth = b * pitch.sin() + z1 * pitch.cos();
        [x, y, depth]
    }
}

/// A polygon in the view: depth, projected corners, colour value.
type Face = (f64, Vec<[f64; 3]>, f64);

/// Every polygon of every frame with its colour value: coloured by the chosen field, else by
/// plastic strain, stress or displacement, whichever varies first; the scale of the chosen
/// node's field, else of the first frame with polygons (None without polygons).
fn surfaces(
    frames: &[Frame],
    choice: Option<Choice>,
    camera: &Oblique,
) -> (Vec<Face>, Option<Scale>) {
    let mut faces: Vec<Face> = Vec::new();
    let mut bar_name = None;
    for f in frames {
        let ne = f.polygons.len();
        let cell = pick(
            &f.cell_data,
            &wanted(
                f,
                choice,
                &["plastic_strain", "mises_top", "von_mises", "damage"],
            ),
            ne,
        );
        let point = pick(
            &f.point_data,
            &wanted(f, choice, &["displacement"]),
            f.points.len(),
        );
        for (e, poly) in f.polygons.iter().enumerate() {
            let q: Vec<[f64; 3]> = poly.iter().map(|&i| camera.project(&f.points[i])).collect();
            let depth = q.iter().map(|p| p[2]).sum::<f64>() / q.len() as f64;
            let v = match (cell, point) {
                (Some(a), _) => magnitude(a, e),
                (None, Some(a)) => {
                    poly.iter().map(|&i| magnitude(a, i)).sum::<f64>() / poly.len() as f64
                }
                _ => 0.0,
            };
            faces.push((depth, q, v));
        }
        let is_chosen = choice.is_some_and(|c| c.node == f.node);
        if (bar_name.is_none() || is_chosen) && ne > 0 {
            bar_name = cell.or(point).map(|a| caption(&f.node, a));
        }
    }
    // the chosen field's range where several pictures share one (if it is the surfaces'
    // field), else the values drawn
    let span = choice
        .filter(|c| {
            frames
                .iter()
                .any(|f| f.node == c.node && !f.polygons.is_empty())
        })
        .and_then(|c| c.span)
        .unwrap_or_else(|| range(faces.iter().map(|f| f.2)));
    let sc = bar_name.map(|name| Scale::new(name, span, false));
    (faces, sc)
}

/// The polygons far to near, shaded by their facing, in the colours of `sc`.
fn paint_surfaces(
    root: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    mut faces: Vec<Face>,
    sc: Option<&Scale>,
    view: &View,
) -> anyhow::Result<()> {
    let fallback;
    let sc = match sc {
        Some(sc) => sc,
        None => {
            fallback = Scale::new(String::new(), range(faces.iter().map(|f| f.2)), false);
            &fallback
        }
    };
    faces.sort_by(|a, b| b.0.total_cmp(&a.0));
    for (_, q, v) in &faces {
        let n = normal(q);
        let light = 0.35 + 0.65 * n[2].abs();
        let c = shade(sc.colour(*v), light);
        let pts: Vec<(i32, i32)> = q.iter().map(|p| view.px(p[0], p[1])).collect();
        root.draw(&Polygon::new(pts, c.filled()))?;
    }
    Ok(())
}

/// A frame's particle field and whether it is a fraction on 0..1.
type ParticleField<'a> = (&'a Frame, Option<(&'a Array, bool)>);

/// The field of the particles of each frame without polygons: a chosen field, else damage
/// (or the joint's broken-bond fraction) on 0..1 where it varies, else the stress or the
/// displacement; and the fields shared by frames (ten joints, one colour bar), each with its
/// span over every frame it colours.
fn particle_fields<'a>(
    frames: &'a [Frame],
    choice: Option<Choice<'a>>,
) -> (Vec<ParticleField<'a>>, Vec<Shared<'a>>) {
    let fields: Vec<ParticleField> = frames
        .iter()
        .filter(|f| f.polygons.is_empty())
        .map(|f| {
            let n = f.points.len();
            let chosen = choice
                .filter(|c| c.node == f.node)
                .and_then(|c| pick_sized(&f.point_data, &[c.field], n));
            let fraction = pick(&f.point_data, &["damage", "broken_bond_fraction"], n);
            let field = match (chosen, fraction) {
                (Some(a), _) => Some((a, false)),
                (None, Some(a)) => Some((a, true)),
                _ => pick(&f.point_data, &["stress", "displacement", "velocity"], n)
                    .map(|a| (a, false)),
            };
            (f, field)
        })
        .collect();
    // one scale per field name, over every frame drawn by it
    let mut shared: Vec<Shared> = Vec::new();
    for (f, field) in &fields {
        let Some((a, fraction)) = field else { continue };
        let given = choice.filter(|c| c.node == f.node && c.field == a.name);
        let span = match given.and_then(|c| c.span) {
            Some(span) => span,
            None if *fraction => (0.0, 1.0),
            None => range((0..f.points.len()).map(|i| magnitude(a, i))),
        };
        match shared.iter_mut().find(|s| s.name == a.name) {
            Some(s) => {
                s.nodes.push(&f.node);
                s.span = (s.span.0.min(span.0), s.span.1.max(span.1));
            }
            None => shared.push(Shared {
                name: &a.name,
                nodes: vec![&f.node],
                span,
                measure: measure(a),
            }),
        }
    }
    (fields, shared)
}

/// The colour scale of each shared particle field, named by its nodes.
fn particle_scales(shared: &[Shared]) -> Vec<Scale> {
    shared
        .iter()
        .map(|s| {
            let who = match s.nodes.as_slice() {
                [one] => one.to_string(),
                [a, b] => format!("{a}, {b}"),
                many => format!(
                    "{}, …, {} ({} nodes)",
                    many[0],
                    many[many.len() - 1],
                    many.len()
                ),
            };
            Scale::new(label(&who, s.name, s.measure), s.span, false)
        })
        .collect()
}

/// The particles far to near as dots, each field in its shared scale (`scales[k]` is
/// `shared[k]`'s).
fn paint_particles(
    root: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    fields: &[ParticleField],
    shared: &[Shared],
    scales: &[Scale],
    camera: &Oblique,
    view: &View,
) -> anyhow::Result<()> {
    for (f, field) in fields {
        let n = f.points.len();
        let r = if n > 20_000 { 1 } else { 2 };
        let sc = field.and_then(|(a, _)| {
            let k = shared.iter().position(|s| s.name == a.name)?;
            scales.get(k)
        });
        let mut order: Vec<(f64, usize)> = f
            .points
            .iter()
            .enumerate()
            .map(|(i, p)| (camera.project(p)[2], i))
            .collect();
        order.sort_by(|a, b| b.0.total_cmp(&a.0));
        for (_, i) in order {
            let q = camera.project(&f.points[i]);
            let c = match (field, sc) {
                (Some((a, _)), Some(sc)) => sc.colour(magnitude(a, i)),
                _ => RGBColor(200, 40, 40),
            };
            root.draw(&Circle::new(view.px(q[0], q[1]), r, c.filled()))?;
        }
    }
    Ok(())
}

/// A field that colours the particles of several frames: its name, the nodes, the span of
/// their values and the measure drawn.
struct Shared<'a> {
    name: &'a str,
    nodes: Vec<&'a str>,
    span: (f64, f64),
    measure: Option<&'static str>,
}

/// Unit normal of a planar polygon (Newell's method).
fn normal(q: &[[f64; 3]]) -> [f64; 3] {
    let mut n = [0.0; 3];
    for i in 0..q.len() {
        let (a, b) = (q[i], q[(i + 1) % q.len()]);
        n[0] += (a[1] - b[1]) * (a[2] + b[2]);
        n[1] += (a[2] - b[2]) * (a[0] + b[0]);
        n[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if l > 0.0 {
        [n[0] / l, n[1] / l, n[2] / l]
    } else {
        [0.0, 0.0, 1.0]
    }
}

/// The colour bar of scale `sc`, the `k`-th of `n` stacked down the right edge: the map,
/// ticks at round values with their numbers, and the caption above it.
fn colour_bar(
    root: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    sc: &Scale,
    k: usize,
    n: usize,
    text: bool,
) -> anyhow::Result<()> {
    let slot = 620 / n.max(1) as i32;
    let (x0, y0, h) = (1075, 100 + k as i32 * slot + 20, slot - 50);
    for j in 0..h {
        let s = 1.0 - j as f64 / (h - 1) as f64;
        root.draw(&Rectangle::new(
            [(x0, y0 + j), (x0 + 24, y0 + j + 1)],
            sc.at(s).filled(),
        ))?;
    }
    root.draw(&Rectangle::new([(x0, y0), (x0 + 24, y0 + h)], BLACK))?;
    if !text {
        return Ok(());
    }
    let font = ("sans-serif", 14).into_font();
    for v in ticks(sc.lo, sc.hi) {
        let y = y0 + ((sc.hi - v) / (sc.hi - sc.lo) * (h - 1) as f64).round() as i32;
        root.draw(&PathElement::new([(x0 + 24, y), (x0 + 30, y)], BLACK))?;
        root.draw(&Text::new(
            crate::plot::tick_label(v, sc.lo, sc.hi),
            (x0 + 33, y - 7),
            font.clone(),
        ))?;
    }
    // the caption above the bar, right-aligned to the picture's edge and kept right of the
    // plot: on as many lines as it needs, broken between words (`node: field (measure) [unit]`)
    let caption = ("sans-serif", 15).into_font();
    let style = caption.clone().into_text_style(root);
    let width = |t: &str| {
        root.estimate_text_size(t, &style)
            .map_or(0, |(w, _)| w as i32)
    };
    let room = 1195 - (PLOT.0 + PLOT.2 + 8);
    let mut lines: Vec<String> = Vec::new();
    for word in sc.label.split(' ') {
        match lines.last_mut() {
            Some(line) if width(&format!("{line} {word}")) <= room => {
                line.push(' ');
                line.push_str(word);
            }
            _ => lines.push(word.to_string()),
        }
    }
    for (k, line) in lines.iter().rev().enumerate() {
        let x = (1195 - width(line)).max(PLOT.0 + PLOT.2 + 8);
        root.draw(&Text::new(
            line.clone(),
            (x, y0 - 22 - 18 * k as i32),
            caption.clone(),
        ))?;
    }
    Ok(())
}

/// Round tick values in `lo..=hi`: 1, 2 or 5 times a power of ten apart, 4 to 10 of them.
fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    let span = hi - lo;
    if !(span > 0.0 && span.is_finite()) {
        return vec![lo];
    }
    let raw = span / 5.0;
    let p = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * p)
        .find(|s| span / s <= 8.0)
        .unwrap_or(10.0 * p);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

/// A length scale at the picture's lower left: a bar of a round length (1, 2 or 5 times a
/// power of ten, about a fifth of the plot's width) and its length in m, mm or µm; None
/// where the view has no scale.
fn scale_bar(
    root: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    px_per_m: f64,
    text: bool,
) -> anyhow::Result<Option<String>> {
    if !(px_per_m.is_finite() && px_per_m > 0.0) {
        return Ok(None);
    }
    let want = 0.2 * PLOT.2 as f64 / px_per_m;
    let p = 10f64.powf(want.log10().floor());
    let len = [1.0, 2.0, 5.0]
        .iter()
        .map(|m| m * p)
        .rfind(|l| *l <= want)
        .unwrap_or(p);
    let label = if len >= 1.0 {
        format!("{} m", round_len(len))
    } else if len >= 1e-3 {
        format!("{} mm", round_len(len * 1e3))
    } else {
        format!("{} µm", round_len(len * 1e6))
    };
    let (x0, y) = (PLOT.0 + 10, PLOT.1 + PLOT.3 + 22);
    let x1 = x0 + (len * px_per_m).round() as i32;
    root.draw(&Rectangle::new([(x0, y), (x1, y + 5)], BLACK.filled()))?;
    for x in [x0, x1] {
        root.draw(&PathElement::new([(x, y - 5), (x, y + 10)], BLACK))?;
    }
    if text {
        root.draw(&Text::new(
            label.clone(),
            (x1 + 10, y - 6),
            ("sans-serif", 16).into_font(),
        ))?;
    }
    Ok(Some(label))
}

/// A round length as written: no trailing zeros.
fn round_len(v: f64) -> String {
    let s = format!("{v:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

#[cfg(test)]
mod tests {
    /// The diverging map is Moreland's cool-to-warm as ParaView and matplotlib (`coolwarm`)
    /// draw it: at nine points of the scale, the colours of his published table (read here
    /// from matplotlib's `coolwarm`, which is built from it) within 2 of 255 per channel;
    /// the ends exact; the middle a grey.
    #[test]
    fn the_diverging_map_is_paraviews_cool_to_warm() {
        let table = [
            (0.0, [59, 76, 192]),
            (0.125, [98, 130, 234]),
            (0.25, [141, 176, 254]),
            (0.375, [185, 208, 249]),
            (0.5, [221, 220, 220]),
            (0.625, [245, 196, 172]),
            (0.75, [244, 152, 122]),
            (0.875, [221, 95, 75]),
            (1.0, [180, 4, 38]),
        ];
        for (s, want) in table {
            let RGBColor(r, g, b) = super::cool_to_warm(s);
            for (got, want) in [r, g, b].into_iter().zip(want) {
                assert!(
                    (got as i32 - want).abs() <= 2,
                    "at {s}: {:?} against {want:?}",
                    (r, g, b)
                );
            }
        }
        assert_eq!(super::cool_to_warm(0.0), RGBColor(59, 76, 192));
        assert_eq!(super::cool_to_warm(1.0), RGBColor(180, 4, 38));
        let RGBColor(r, g, b) = super::cool_to_warm(0.5);
        assert!(r.abs_diff(g) <= 1 && g.abs_diff(b) <= 1, "{r} {g} {b}");
        // the table read is the computed map within one level, between its entries too
        for k in 0..=4000 {
            let s = k as f64 / 4000.0;
            let (RGBColor(a, b, c), RGBColor(x, y, z)) =
                (super::cool_to_warm(s), super::cool_to_warm_msh(s));
            assert!(
                a.abs_diff(x) <= 1 && b.abs_diff(y) <= 1 && c.abs_diff(z) <= 1,
                "at {s}"
            );
        }
    }

    use super::*;

    /// A tall box, 1 × 2 × 4 (x, y, z): its corners.
    fn tall_box() -> Vec<Frame> {
        let mut points = Vec::new();
        for k in 0..8 {
            points.push([
                (k & 1) as f64,
                2.0 * ((k >> 1) & 1) as f64,
                4.0 * (k >> 2) as f64,
            ]);
        }
        vec![Frame {
            node: "box".into(),
            grid: None,
            points,
            polygons: Vec::new(),
            point_data: Vec::new(),
            cell_data: Vec::new(),
        }]
    }

    /// The automatic camera lays the longest axis (z) across and the second (y) up; with
    /// `--up z --yaw 0 --pitch 0` z is drawn up, x across and y is the depth (a side view),
    /// and a turn of 90° brings y across.
    #[test]
    fn the_camera_puts_the_chosen_axis_up() {
        let frames = tall_box();
        let auto = Oblique::of(&frames, Camera::default());
        assert_eq!(auto.axes, [2, 1, 0]);
        let side = Camera::from_args(Some("z"), Some(0.0), Some(0.0)).unwrap();
        let cam = Oblique::of(&frames, side);
        assert_eq!(cam.axes, [0, 2, 1]);
        // the top corner (1, 2, 4) relative to the centre (0.5, 1, 2): across 0.5, up 2, depth 1
        let q = cam.project(&[1.0, 2.0, 4.0]);
        assert!(
            (q[0] - 0.5).abs() < 1e-12 && (q[1] - 2.0).abs() < 1e-12,
            "{q:?}"
        );
        assert!((q[2] - 1.0).abs() < 1e-12, "{q:?}");
        let turned = Oblique::of(
            &frames,
            Camera::from_args(Some("z"), Some(90.0), Some(0.0)).unwrap(),
        );
        let q = turned.project(&[1.0, 2.0, 4.0]);
        assert!(
            (q[0] - 1.0).abs() < 1e-12 && (q[1] - 2.0).abs() < 1e-12,
            "{q:?}"
        );
        for (up, yaw, pitch) in [
            (Some("w"), None, None),
            (None, Some(200.0), None),
            (None, None, Some(f64::NAN)),
        ] {
            assert!(
                Camera::from_args(up, yaw, pitch).is_err(),
                "{up:?} {yaw:?} {pitch:?}"
            );
        }
    }
}
