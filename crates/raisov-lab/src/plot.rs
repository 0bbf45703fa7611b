//! Line charts of the paper's figures with plotters, as PNG and SVG, written atomically
//! (SVG rendered to a string; PNG rendered to a temporary file in the same directory, then
//! renamed). Only finite points are drawn; on a log axis, only positive ones.
//!
//! Text is drawn with DejaVu Sans embedded in the binary (`fonts/DejaVuSans.ttf`, Bitstream
//! Vera licence, `fonts/DejaVuSans-LICENSE.txt`) through plotters' `ab_glyph` renderer, so no
//! system font library is needed. Each panel's legend stands in its own column right of the
//! plot area, below it the abbreviations of [`ABBREVIATIONS`]; a method has the same colour in
//! every figure ([`method_colour`]).

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use raisov::error::{Error, Result};
use raisov::io::write_atomic;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The font every chart uses, embedded.
const FONT: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");
/// The family name charts ask for.
const FAMILY: &str = "sans-serif";

/// The abbreviations of the legends, spelled out under every legend.
pub const ABBREVIATIONS: [&str; 5] = [
    "SLIM: single-level integration method",
    "FAS: full-approximation-scheme multigrid",
    "RaISoV: Wu & Tendick's multigrid integrator",
    "eps: RaISoV's state-switch threshold",
    "T_inf: steady-state stress",
];

/// Register the embedded font under [`FAMILY`] once per process.
fn register() -> Result<()> {
    static PARSED: OnceLock<bool> = OnceLock::new();
    if *PARSED.get_or_init(|| register_font(FAMILY, FontStyle::Normal, FONT).is_ok()) {
        Ok(())
    } else {
        Err(Error::param(
            "plot",
            "the embedded font fonts/DejaVuSans.ttf does not parse",
        ))
    }
}

/// The colour of a method in every figure, from its label ([`crate::paper::experiments::Meth::label`]):
/// SLIM RK4 black, SLIM symplectic Euler orange, SLIM central difference brown, FAS blue,
/// RaISoV `paper` reading greens (default ε dark, best ε light), RaISoV `correction` reading
/// red (default ε) and purple (best ε). Other labels get a fixed colour from their text.
pub fn method_colour(label: &str) -> RGBColor {
    let known: [(&str, RGBColor); 8] = [
        ("SLIM rk4", RGBColor(0, 0, 0)),
        ("SLIM symplectic-euler", RGBColor(230, 120, 0)),
        ("SLIM central-difference", RGBColor(140, 86, 75)),
        ("FAS", RGBColor(31, 90, 200)),
        ("RaISoV paper, eps default", RGBColor(20, 120, 40)),
        ("RaISoV paper, eps best", RGBColor(120, 200, 90)),
        ("RaISoV correction, eps default", RGBColor(214, 39, 40)),
        ("RaISoV correction, eps best", RGBColor(148, 80, 190)),
    ];
    if let Some((_, c)) = known.iter().find(|(p, _)| label.starts_with(p)) {
        return *c;
    }
    let h = label
        .bytes()
        .fold(0usize, |h, b| h.wrapping_mul(31).wrapping_add(b as usize));
    let (r, g, b) = Palette99::pick(h).rgb();
    RGBColor(r, g, b)
}

/// One panel: a title, axis labels and named series of (x, y) points.
#[derive(Clone, Debug, Default)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<(String, Vec<(f64, f64)>)>,
    /// Logarithmic x axis.
    pub log_x: bool,
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
                    .filter(|(x, y)| {
                        x.is_finite()
                            && y.is_finite()
                            && (!p.log_x || *x > 0.0)
                            && (!p.log_y || *y > 0.0)
                    })
                    .collect(),
            )
        })
        .collect()
}

/// A tick label: at most three decimals, trailing zeros dropped.
fn tick(x: f64) -> String {
    let s = format!("{x:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.into()
    }
}

/// Width of the legend column (px).
const LEGEND_WIDTH: u32 = 330;

/// The range of one axis over `v`, padded; positive on a log axis.
fn axis_range(v: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (mut a, mut b) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    });
    if !(a.is_finite() && b.is_finite()) {
        (a, b) = if log { (1.0, 10.0) } else { (0.0, 1.0) };
    }
    if log {
        if b <= a {
            (a, b) = (a / 2.0, b * 2.0);
        }
        (a * 0.7, b * 1.4)
    } else {
        if b <= a {
            (a, b) = (a - 0.5, b + 0.5);
        }
        let pad = 0.05 * (b - a);
        (a - pad, b + pad)
    }
}

fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    series: &[(String, Vec<(f64, f64)>)],
) -> Result<()> {
    let font = (FAMILY, 13).into_font();
    let small = (FAMILY, 11).into_font().color(&RGBColor(80, 80, 80));
    let mut y = 40;
    for (name, pts) in series {
        let col = method_colour(name);
        area.draw(&PathElement::new(
            vec![(6, y), (30, y)],
            col.stroke_width(3),
        ))
        .map_err(plot_err)?;
        let text = if pts.is_empty() {
            format!("{name} (nothing to draw)")
        } else {
            name.clone()
        };
        area.draw(&Text::new(text, (36, y - 7), font.clone()))
            .map_err(plot_err)?;
        y += 20;
    }
    y += 10;
    for a in ABBREVIATIONS {
        area.draw(&Text::new(a, (6, y - 6), small.clone()))
            .map_err(plot_err)?;
        y += 15;
    }
    Ok(())
}

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> Result<()> {
    let series = drawable(p);
    let (w, _) = area.dim_in_pixel();
    let (plot_area, legend_area) = area.split_horizontally(w.saturating_sub(LEGEND_WIDTH));
    let all = || series.iter().flat_map(|s| s.1.iter().copied());
    let (x0, x1) = axis_range(all().map(|q| q.0), p.log_x);
    let (y0, y1) = axis_range(all().map(|q| q.1), p.log_y);
    let mut chart = ChartBuilder::on(&plot_area);
    chart
        .caption(&p.title, (FAMILY, 17))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70);
    macro_rules! body {
        ($c:expr) => {{
            let mut c = $c;
            c.configure_mesh()
                .x_desc(p.x_label.as_str())
                .y_desc(p.y_label.as_str())
                .label_style((FAMILY, 12))
                .x_label_formatter(&|x| tick(*x))
                .y_label_formatter(&|y| format!("{y:.0e}"))
                .draw()
                .map_err(plot_err)?;
            for (name, pts) in &series {
                if pts.is_empty() {
                    continue;
                }
                let col = method_colour(name);
                c.draw_series(LineSeries::new(pts.iter().copied(), col.stroke_width(2)))
                    .map_err(plot_err)?;
                if p.markers {
                    c.draw_series(pts.iter().map(|&q| Circle::new(q, 4, col.filled())))
                        .map_err(plot_err)?;
                }
            }
        }};
    }
    match (p.log_x, p.log_y) {
        (false, false) => body!(chart.build_cartesian_2d(x0..x1, y0..y1).map_err(plot_err)?),
        (false, true) => body!(chart
            .build_cartesian_2d(x0..x1, (y0..y1).log_scale())
            .map_err(plot_err)?),
        (true, false) => body!(chart
            .build_cartesian_2d((x0..x1).log_scale(), y0..y1)
            .map_err(plot_err)?),
        (true, true) => body!(chart
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(plot_err)?),
    }
    draw_legend(&legend_area, &series)
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
    register()?;
    let size = (900 + LEGEND_WIDTH, 420 * panels.len() as u32);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Every method of the experiments has its own colour, the same on every call.
    #[test]
    fn methods_have_distinct_fixed_colours() {
        let labels = [
            "SLIM rk4",
            "SLIM symplectic-euler",
            "SLIM central-difference",
            "FAS multigrid",
            "RaISoV paper, eps default",
            "RaISoV paper, eps best (1.2e-5 m)",
            "RaISoV correction, eps default",
            "RaISoV correction, eps best (0: state only)",
        ];
        let c: Vec<RGBColor> = labels.iter().map(|l| method_colour(l)).collect();
        for i in 0..c.len() {
            for j in 0..i {
                assert_ne!(c[i], c[j], "{} and {}", labels[i], labels[j]);
            }
        }
        assert_eq!(
            method_colour("anything else"),
            method_colour("anything else")
        );
    }

    /// The embedded font draws text: the legend column, empty of anything but text, gets
    /// dark pixels, in a bitmap rendered in memory.
    #[test]
    fn legend_text_is_drawn_with_the_embedded_font() {
        register().unwrap();
        let (w, h) = (900 + LEGEND_WIDTH, 420);
        let mut buf = vec![0u8; 3 * (w * h) as usize];
        let panel = Panel {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            series: vec![("FAS multigrid".into(), vec![(1.0, 1.0), (2.0, 0.1)])],
            log_x: false,
            log_y: true,
            markers: false,
        };
        {
            let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            draw_all(root, &[panel]).unwrap();
        }
        // Text pixels of the legend column right of its colour swatches (x > 36).
        let dark = (0..h)
            .flat_map(|y| (900 + 36..w).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let i = 3 * (y * w + x) as usize;
                buf[i..i + 3].iter().all(|&c| c < 128)
            })
            .count();
        assert!(dark > 200, "only {dark} dark pixels in the legend column");
    }
}
