//! Fragment-size histograms (`cosim plot RUN --fragments`): for every node of a run that
//! wrote a fragment table (`NODE/fragments.csv`, the solid node's fragments of its last
//! frame), the counts of fragments by width and by thickness, side by side, in one PNG.

use crate::export::{Table, fragment_tables};
use crate::plot::{font_ready, png_whole};
use anyhow::bail;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Bins of a histogram of `values`: `n` equal bins over [0, max·(1 + 1e-9)], their lower
/// edges and counts. The bin count is √N rounded up, between 5 and 30.
pub fn bins(values: &[f64]) -> (f64, Vec<usize>) {
    let n = ((values.len() as f64).sqrt().ceil() as usize).clamp(5, 30);
    let max = values.iter().cloned().fold(0.0, f64::max);
    let width = if max > 0.0 {
        max * (1.0 + 1e-9) / n as f64
    } else {
        1.0
    };
    let mut counts = vec![0; n];
    for &v in values {
        if v.is_finite() && v >= 0.0 {
            counts[((v / width) as usize).min(n - 1)] += 1;
        }
    }
    (width, counts)
}

/// The histograms of every fragment table of the runs `runs` (their folders), one PNG per run
/// and node in `out` (`RUN_NODE_fragments.png`); the files written. A run without a table is
/// an error naming it.
pub fn fragment_histograms(runs: &[PathBuf], out: &Path) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(out)
        .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", out.display()))?;
    let mut written = Vec::new();
    for run in runs {
        let tables = fragment_tables(run)?;
        if tables.is_empty() {
            bail!(
                "{}: no node wrote a fragment table (NODE/fragments.csv: a solid node with a \
                 damage model writes one with each output frame)",
                run.display()
            );
        }
        let name = run
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "run".into());
        for (table, t) in &tables {
            let png = out.join(format!("{name}_{table}.png"));
            let node = table.trim_end_matches("_fragments");
            png_whole(&png, |tmp| draw(tmp, &format!("{name}: {node}"), t))?;
            written.push(png);
        }
    }
    Ok(written)
}

/// The two histograms of one table (widths and thicknesses in mm) into `path`.
fn draw(path: &Path, title: &str, t: &Table) -> anyhow::Result<()> {
    let mm = |key: &str| -> Vec<f64> { t.column(key, 1).iter().map(|v| v * 1e3).collect() };
    let (width, thickness) = (mm("width"), mm("thickness"));
    if width.is_empty() {
        bail!("{title}: the fragment table has no fragments");
    }
    let time = t.column("time", 1).first().copied().unwrap_or(f64::NAN);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let text = font_ready();
    let err = |e: &dyn std::fmt::Display| anyhow::anyhow!("plot {}: {e}", path.display());
    let root = BitMapBackend::new(path, (1100, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let root = if text {
        root.titled(
            &format!(
                "{title} — {} fragments at t = {time:.3e} s; mean width {:.2} mm, thickness {:.2} mm",
                width.len(),
                mean(&width),
                mean(&thickness)
            ),
            ("sans-serif", 20),
        )
        .map_err(|e| err(&e))?
    } else {
        root
    };
    let panels = root.split_evenly((1, 2));
    for (area, (values, label)) in panels
        .iter()
        .zip([(&width, "width [mm]"), (&thickness, "thickness [mm]")])
    {
        let (w, counts) = bins(values);
        let top = *counts.iter().max().unwrap_or(&1) as f64 * 1.1 + 0.5;
        let mut b = ChartBuilder::on(area);
        b.margin(15);
        if text {
            b.x_label_area_size(45).y_label_area_size(55);
        }
        let mut chart = b
            .build_cartesian_2d(0.0..w * counts.len() as f64, 0.0..top)
            .map_err(|e| err(&e))?;
        let mut mesh = chart.configure_mesh();
        if text {
            mesh.x_desc(label)
                .y_desc("fragments")
                .label_style(("sans-serif", 13));
        } else {
            mesh.x_labels(0).y_labels(0);
        }
        mesh.draw().map_err(|e| err(&e))?;
        chart
            .draw_series(counts.iter().enumerate().map(|(i, &c)| {
                let x0 = i as f64 * w;
                Rectangle::new(
                    [(x0, 0.0), (x0 + w, c as f64)],
                    RGBColor(31, 119, 180).filled(),
                )
            }))
            .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_count_every_value_once_and_put_the_largest_in_the_last_bin() {
        let v: Vec<f64> = (1..=49).map(|i| i as f64 * 0.1).collect();
        let (w, c) = bins(&v);
        assert_eq!(c.len(), 7);
        assert_eq!(c.iter().sum::<usize>(), 49);
        assert!((w * 7.0 - 4.9).abs() < 1e-6);
        assert_eq!(c, vec![7; 7]);
        // few values: at least five bins; none below zero or NaN is counted
        let (_, c) = bins(&[1.0, 2.0, f64::NAN, -1.0]);
        assert_eq!((c.len(), c.iter().sum::<usize>()), (5, 2));
    }

    #[test]
    fn a_run_without_a_fragment_table_is_refused_by_name() {
        let dir = std::env::temp_dir().join(format!("cosim-hist-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("ring")).unwrap();
        let e = fragment_histograms(std::slice::from_ref(&dir), &dir.join("plots"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("no node wrote a fragment table"), "{e}");
        std::fs::write(
            dir.join("ring/fragments.csv"),
            "time,fragment,particles,mass,x,y,z,vx,vy,vz,speed,width,thickness\n\
             6e-5,0,40,0.1,0,0,0,1,0,0,1,0.008,0.0035\n\
             6e-5,1,30,0.08,0,0,0,1,0,0,1,0.006,0.0031\n",
        )
        .unwrap();
        let files = fragment_histograms(std::slice::from_ref(&dir), &dir.join("plots")).unwrap();
        assert_eq!(files.len(), 1);
        let png = std::fs::read(&files[0]).unwrap();
        assert_eq!(&png[1..4], b"PNG");
        std::fs::write(dir.join("ring/fragments.csv"), "time,width\n6e-5,abc\n").unwrap();
        let e = fragment_histograms(std::slice::from_ref(&dir), &dir.join("plots"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("'abc' is not a number"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
