//! Line charts of the paper's figures with plotters, as PNG and SVG, written atomically
//! (SVG rendered to a string; PNG rendered to a temporary file in the same directory, then
//! renamed). Only finite points are drawn; on a log axis, only positive ones.

use crate::error::{Error, Result};
use crate::io::write_atomic;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// One panel: a title, axis labels and named series of (x, y) points.
#[derive(Clone, Debug, Default)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<(String, Vec<(f64, f64)>)>,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// Mark every point (for short series; a single point draws no line).
    pub markers: bool,
}

fn plot_err(e: impl std::fmt::Debug) -> Error {
    Error::param("plot", format!("{e:?}"))
}

/// Points that can be drawn on this panel.
fn drawable(p: &Panel) -> Vec<(String, Vec<(f64, f64)>)> {
    p.series
        .iter()
        .map(|(n, pts)| {
            (
                n.clone(),
                pts.iter()
                    .copied()
                    .filter(|(x, y)| x.is_finite() && y.is_finite() && (!p.log_y || *y > 0.0))
                    .collect(),
            )
        })
        .collect()
}

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> Result<()> {
    let series = drawable(p);
    let all: Vec<(f64, f64)> = series.iter().flat_map(|s| s.1.iter().copied()).collect();
    let (mut x0, mut x1) = all
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), q| {
            (a.min(q.0), b.max(q.0))
        });
    let (mut y0, mut y1) = all
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), q| {
            (a.min(q.1), b.max(q.1))
        });
    if !(x0.is_finite() && x1.is_finite()) {
        (x0, x1) = (0.0, 1.0);
    }
    if !(y0.is_finite() && y1.is_finite()) {
        (y0, y1) = (1.0, 10.0);
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    let mut chart = ChartBuilder::on(area);
    chart
        .caption(&p.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70);
    let colors = |i: usize| Palette99::pick(i).to_rgba();
    macro_rules! body {
        ($c:expr) => {{
            let mut c = $c;
            c.configure_mesh()
                .x_desc(p.x_label.as_str())
                .y_desc(p.y_label.as_str())
                .y_label_formatter(&|y| format!("{y:.0e}"))
                .draw()
                .map_err(plot_err)?;
            for (i, (name, pts)) in series.iter().enumerate() {
                if pts.is_empty() {
                    continue;
                }
                let col = colors(i);
                c.draw_series(LineSeries::new(pts.iter().copied(), col.stroke_width(2)))
                    .map_err(plot_err)?
                    .label(name.as_str())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2))
                    });
                if p.markers {
                    c.draw_series(pts.iter().map(|&q| Circle::new(q, 4, col.filled())))
                        .map_err(plot_err)?;
                }
            }
            c.configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .position(SeriesLabelPosition::UpperRight)
                .draw()
                .map_err(plot_err)?;
        }};
    }
    if p.log_y {
        let (lo, hi) = (y0 * 0.7, y1 * 1.4);
        body!(chart
            .build_cartesian_2d(x0..x1, (lo..hi).log_scale())
            .map_err(plot_err)?);
    } else {
        let pad = 0.05 * (y1 - y0).abs().max(1e-12);
        body!(chart
            .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
            .map_err(plot_err)?);
    }
    Ok(())
}

fn draw_all<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, panels: &[Panel]) -> Result<()> {
    root.fill(&WHITE).map_err(plot_err)?;
    let areas = root.split_evenly((panels.len(), 1));
    for (a, p) in areas.iter().zip(panels) {
        draw_panel(a, p)?;
    }
    root.present().map_err(plot_err)?;
    Ok(())
}

/// Write `stem.svg` and `stem.png` under `dir`: the panels stacked vertically.
pub fn write_chart(dir: &Path, stem: &str, panels: &[Panel]) -> Result<Vec<PathBuf>> {
    let size = (900u32, 420 * panels.len() as u32);
    let svg_path = dir.join(format!("{stem}.svg"));
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        draw_all(root, panels)?;
    }
    write_atomic(&svg_path, |w| w.write_all(svg.as_bytes()))?;
    let png_path = dir.join(format!("{stem}.png"));
    let tmp = dir.join(format!(".{stem}.{}.tmp.png", std::process::id()));
    {
        let root = BitMapBackend::new(&tmp, size).into_drawing_area();
        draw_all(root, panels)?;
    }
    std::fs::rename(&tmp, &png_path).map_err(|e| Error::io(&png_path, e))?;
    Ok(vec![png_path, svg_path])
}
