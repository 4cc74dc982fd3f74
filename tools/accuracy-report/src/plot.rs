//! PNG plots for the accuracy report, over plain data that the caller fills in.
//!
//! * [`error_vs_time`]: a log-log scatter of error against run time, one colour and
//!   marker per group, with the Pareto front drawn as a staircase and its points labelled.
//! * [`scanline`]: intensity along one scanline in three stacked panels (red, green, blue),
//!   in the manner of Goral et al. 1984, Figures 6 and 7.
//!
//! Text uses DejaVu Sans embedded at compile time (the `dejavu` crate), registered with
//! plotters' `ab_glyph` feature (which sizes the text), and drawn by [`canvas`] with ab_glyph
//! directly, so nothing depends on the fonts of the machine: CI machines have none. The
//! images are rasterised into memory and written as PNG with the workspace's `image` crate.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::element::{DashedPathElement, Drawable, MultiLineText, PointCollection};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::FontStyle;
use plotters_backend::{BackendCoord, DrawingErrorKind};

mod canvas;

use canvas::Canvas;

/// Size of the [`error_vs_time`] image in pixels.
pub const ERROR_VS_TIME_SIZE: (u32, u32) = (1200, 800);
/// Size of the [`scanline`] image in pixels.
pub const SCANLINE_SIZE: (u32, u32) = (1200, 1000);
/// Errors at or below zero cannot go on a log axis: [`error_vs_time`] draws them at this
/// value instead (and says how many it moved in a note under the plot). Below the error of
/// any f64 computation of values near 1.
pub const ERROR_FLOOR: f64 = 1e-17;
/// Times at or below zero (a run faster than the clock's resolution) are drawn at this value,
/// 1 ns, likewise: a floor as low as the error's would squeeze every real time into a corner.
pub const TIME_FLOOR: f64 = 1e-9;

/// The font family name the embedded font is registered under; plotters' own default
/// text styles ask for it too.
const FONT: &str = "sans-serif";

/// One run in the error-versus-time plot.
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// Written next to the point when it is on the Pareto front.
    pub label: String,
    /// Points of one group share a colour, a marker and a legend entry.
    pub group: String,
    pub time_s: f64,
    pub error: f64,
}

/// One curve of the scanline plot: intensity in the three bands along the scanline.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    pub label: String,
    /// Position along the scanline, one per sample.
    pub x: Vec<f64>,
    /// Red, green and blue intensity, one per sample (as many as `x`).
    pub rgb: Vec<[f64; 3]>,
}

#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("nothing to plot: {0} is empty")]
    Empty(&'static str),
    #[error("nothing to plot: none of the {0} has a finite value")]
    NoFiniteData(&'static str),
    #[error("curve {label:?} has {x} positions but {rgb} colour samples")]
    CurveLength { label: String, x: usize, rgb: usize },
    #[error("{labels} break labels for {breaks} breaks (give one per break, or none)")]
    BreakLabels { breaks: usize, labels: usize },
    #[error("the embedded DejaVu Sans font could not be registered with plotters")]
    Font,
    #[error("drawing the plot: {0}")]
    Draw(String),
    #[error("writing {path}: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: image::ImageError,
    },
}

impl<E: std::error::Error + Send + Sync> From<DrawingAreaErrorKind<E>> for PlotError {
    fn from(e: DrawingAreaErrorKind<E>) -> Self {
        PlotError::Draw(e.to_string())
    }
}

/// Indices of the Pareto-optimal points (no other point has both time <= and error <= with
/// one strictly less), sorted by time (then error, then index).
///
/// Points with a NaN time or error are left out. Points that are exactly equal do not
/// dominate each other, so duplicates of a front point are all on the front.
pub fn pareto_front(points: &[Point]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len())
        .filter(|&i| !points[i].time_s.is_nan() && !points[i].error.is_nan())
        .collect();
    order.sort_by(|&a, &b| {
        let (pa, pb) = (&points[a], &points[b]);
        pa.time_s
            .total_cmp(&pb.time_s)
            .then(pa.error.total_cmp(&pb.error))
            .then(a.cmp(&b))
    });
    // Sweep in time order: a point is on the front when its error is below every error seen
    // so far, or when it repeats the last front point exactly. Anything else has an earlier
    // point with time <= and error <=, one of them strictly.
    let mut front: Vec<usize> = Vec::new();
    for i in order {
        let p = &points[i];
        let keep = match front.last() {
            None => true,
            Some(&j) => {
                let q = &points[j];
                p.error < q.error || (p.error == q.error && p.time_s == q.time_s)
            }
        };
        if keep {
            front.push(i);
        }
    }
    front
}

/// Log-log scatter of error (y) versus time (x), one colour+marker per distinct `group`
/// (legend, in order of first appearance), the Pareto front drawn as a staircase through its
/// points and its points labelled with `label` (small text). Written as a 1200×800 PNG.
///
/// Points with a NaN or infinite time or error are skipped. Values at or below zero cannot be
/// shown on a log axis: an error <= 0 is clamped to [`ERROR_FLOOR`] (1e-17) and a time <= 0
/// to [`TIME_FLOOR`] (1e-9 s). A note under the plot says how many points were skipped or
/// clamped. The front is computed from the values as given (before clamping).
///
/// Errors: [`PlotError::Empty`] for no points, [`PlotError::NoFiniteData`] when every point
/// is skipped.
pub fn error_vs_time(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    points: &[Point],
) -> Result<(), PlotError> {
    if points.is_empty() {
        return Err(PlotError::Empty("points"));
    }
    let finite: Vec<usize> = (0..points.len())
        .filter(|&i| points[i].time_s.is_finite() && points[i].error.is_finite())
        .collect();
    if finite.is_empty() {
        return Err(PlotError::NoFiniteData("points"));
    }
    let skipped = points.len() - finite.len();
    let clamped_errors = finite.iter().filter(|&&i| points[i].error <= 0.0).count();
    let clamped_times = finite.iter().filter(|&&i| points[i].time_s <= 0.0).count();
    let at = |i: usize| {
        (
            points[i].time_s.max(TIME_FLOOR),
            points[i].error.max(ERROR_FLOOR),
        )
    };
    let subset: Vec<Point> = finite.iter().map(|&i| points[i].clone()).collect();
    let front: Vec<usize> = pareto_front(&subset)
        .into_iter()
        .map(|k| finite[k])
        .collect();

    let mut groups: Vec<&str> = Vec::new();
    for &i in &finite {
        if !groups.contains(&points[i].group.as_str()) {
            groups.push(&points[i].group);
        }
    }

    let (xs, ys): (Vec<f64>, Vec<f64>) = finite.iter().map(|&i| at(i)).unzip();
    let x_range = log_range(&xs);
    let y_range = log_range(&ys);

    register_font()?;
    let (w, h) = ERROR_VS_TIME_SIZE;
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = Canvas::new(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, (FONT, 30))
            .margin(20)
            .margin_bottom(36) // room for the note on skipped or clamped points
            .x_label_area_size(70)
            .y_label_area_size(100)
            .build_cartesian_2d(x_range.log_scale(), y_range.log_scale())?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .axis_desc_style((FONT, 22))
            .label_style((FONT, 17))
            .x_label_formatter(&|v| tick_label(*v))
            .y_label_formatter(&|v| tick_label(*v))
            .bold_line_style(BLACK.mix(0.15))
            .light_line_style(BLACK.mix(0.05))
            .draw()?;

        // The front first, so that the markers are drawn over it.
        let stairs: Vec<(f64, f64)> = front
            .windows(2)
            .flat_map(|pair| {
                let (a, b) = (at(pair[0]), at(pair[1]));
                [a, (b.0, a.1)]
            })
            .chain(front.last().map(|&i| at(i)))
            .collect();
        chart
            .draw_series(LineSeries::new(stairs.clone(), BLACK.stroke_width(2)))?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
        chart.draw_series(
            front
                .iter()
                .map(|&i| Circle::new(at(i), 10, BLACK.stroke_width(1))),
        )?;

        for (g, name) in groups.iter().enumerate() {
            let colour = PALETTE[g % PALETTE.len()];
            chart
                .draw_series(
                    finite
                        .iter()
                        .filter(|&&i| points[i].group == *name)
                        .map(|&i| marker(g, at(i), colour)),
                )?
                .label(*name)
                .legend(move |c| marker(g, c, colour));
        }

        // Legend in whichever corner of the plotting area covers the fewest points.
        let mut legend_lines = vec!["Pareto front"];
        legend_lines.extend(groups.iter().copied());
        let legend_font: TextStyle = (FONT, 18).into();
        let (legend_w, legend_h) = legend_size(&legend_lines, &legend_font)?;
        let area = chart.plotting_area();
        let (px, py) = area.get_pixel_range();
        let marks: Vec<(i32, i32)> = finite
            .iter()
            .map(|&i| chart.backend_coord(&at(i)))
            .collect();
        let inset = 10;
        let corners = [
            (px.end - legend_w - inset, py.start + inset),
            (px.start + inset, py.end - legend_h - inset),
            (px.start + inset, py.start + inset),
            (px.end - legend_w - inset, py.end - legend_h - inset),
        ];
        let (lx, ly) = corners
            .into_iter()
            .min_by_key(|&(cx, cy)| {
                marks
                    .iter()
                    .filter(|&&(mx, my)| {
                        mx >= cx - 10
                            && mx <= cx + legend_w + 10
                            && my >= cy - 10
                            && my <= cy + legend_h + 10
                    })
                    .count()
            })
            .unwrap_or(corners[0]);
        let legend_box = Rect::new(lx, ly, legend_w, legend_h);
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::Coordinate(
                lx - px.start,
                ly - py.start,
            ))
            .margin(LEGEND_MARGIN)
            .legend_area_size(LEGEND_SAMPLE)
            .label_font(legend_font)
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK.mix(0.5))
            .draw()?;

        // Labels of the front points, each placed where it overlaps no other label, marker
        // or the legend, when such a place is near.
        let label_font: TextStyle = (FONT, 15).into();
        let mut taken: Vec<Rect> = marks.iter().map(|&(x, y)| Rect::around(x, y, 7)).collect();
        taken.extend(stairs.windows(2).map(|seg| {
            let (a, b) = (chart.backend_coord(&seg[0]), chart.backend_coord(&seg[1]));
            let (x0, y0) = (a.0.min(b.0), a.1.min(b.1));
            Rect::new(x0 - 1, y0 - 1, (a.0 - b.0).abs() + 2, (a.1 - b.1).abs() + 2)
        }));
        taken.push(legend_box);
        let bounds = Rect::new(px.start, py.start, px.end - px.start, py.end - py.start);
        for &i in &front {
            let text = points[i].label.as_str();
            if text.is_empty() {
                continue;
            }
            let (tw, th) = root.estimate_text_size(text, &label_font)?;
            // Plotters' text height is about the ascent: leave room for descenders too.
            let (tw, th) = (tw as i32, th as i32 * 5 / 4 + 2);
            let (x, y) = chart.backend_coord(&at(i));
            let candidates = [
                (x + 12, y - th - 4),
                (x + 12, y + 4),
                (x - tw - 12, y - th - 4),
                (x - tw - 12, y + 4),
                (x + 12, y - th / 2),
                (x - tw - 12, y - th / 2),
                (x - tw / 2, y - th - 14),
                (x - tw / 2, y + 14),
                (x + 12, y - 2 * th - 10),
                (x + 12, y + th + 10),
                (x - tw - 12, y - 2 * th - 10),
                (x - tw - 12, y + th + 10),
            ];
            let rects = candidates.map(|(cx, cy)| Rect::new(cx, cy, tw, th));
            let spot = rects
                .iter()
                .find(|r| bounds.contains(r) && taken.iter().all(|t| !t.overlaps(r)))
                .or_else(|| rects.iter().find(|r| bounds.contains(r)))
                .unwrap_or(&rects[0]);
            root.draw(&Text::new(text, (spot.x, spot.y), label_font.clone()))?;
            taken.push(*spot);
        }

        let mut notes = Vec::new();
        if skipped > 0 {
            notes.push(format!(
                "{skipped} point(s) with a NaN or infinite value not shown"
            ));
        }
        if clamped_errors > 0 {
            notes.push(format!(
                "{clamped_errors} point(s) with an error <= 0 drawn at {ERROR_FLOOR:e}"
            ));
        }
        if clamped_times > 0 {
            notes.push(format!(
                "{clamped_times} point(s) with a time <= 0 drawn at {TIME_FLOOR:e} s"
            ));
        }
        if !notes.is_empty() {
            root.draw(&Text::new(
                notes.join("; "),
                (12, h as i32 - 28),
                (FONT, 15).into_font().color(&BLACK.mix(0.7)),
            ))?;
        }
        root.present()?;
    }
    save_png(path, &buf, (w, h))
}

/// RGB scanline intensity plot like Goral et al. 1984 Figures 6 and 7: three stacked panels
/// (red, green, blue band), x = position along the scanline, y = intensity. Each curve is one
/// line per panel in a distinct colour and dash pattern, named in a legend above the panels;
/// the first curve is the reference, drawn thicker and black. Vertical dashed separators are
/// drawn at `breaks` (positions where the scanline crosses from one wall to the next), with
/// `break_labels[i]` written above the panels at `breaks[i]` (give one label per break, or
/// none). Written as a 1200×1000 PNG.
///
/// Samples with a NaN or infinite position or intensity are skipped (the line is broken
/// there); NaN breaks are skipped. The y axis of each band runs from 0 (or the lowest value,
/// if negative) to a little above the highest value.
///
/// Errors: [`PlotError::Empty`] for no curves, [`PlotError::CurveLength`] when a curve's `x`
/// and `rgb` differ in length, [`PlotError::BreakLabels`] for a label count other than 0 or
/// `breaks.len()`, [`PlotError::NoFiniteData`] when no curve has a finite sample.
pub fn scanline(
    path: &Path,
    title: &str,
    x_label: &str,
    curves: &[Curve],
    breaks: &[f64],
    break_labels: &[&str],
) -> Result<(), PlotError> {
    if curves.is_empty() {
        return Err(PlotError::Empty("curves"));
    }
    if let Some(c) = curves.iter().find(|c| c.x.len() != c.rgb.len()) {
        return Err(PlotError::CurveLength {
            label: c.label.clone(),
            x: c.x.len(),
            rgb: c.rgb.len(),
        });
    }
    if !break_labels.is_empty() && break_labels.len() != breaks.len() {
        return Err(PlotError::BreakLabels {
            breaks: breaks.len(),
            labels: break_labels.len(),
        });
    }
    let samples = |c: &Curve, band: usize| -> Vec<Option<(f64, f64)>> {
        c.x.iter()
            .zip(&c.rgb)
            .map(|(&x, rgb)| (x.is_finite() && rgb[band].is_finite()).then_some((x, rgb[band])))
            .collect()
    };
    let xs: Vec<f64> = curves
        .iter()
        .flat_map(|c| (0..3).flat_map(move |b| samples(c, b)))
        .flatten()
        .map(|(x, _)| x)
        .collect();
    if xs.is_empty() {
        return Err(PlotError::NoFiniteData("curves"));
    }
    let x_range = linear_range(&xs);

    register_font()?;
    let (w, h) = SCANLINE_SIZE;
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        // `full` draws in pixel coordinates of the image, as `backend_coord` gives them.
        let full = Canvas::new(&mut buf, (w, h)).into_drawing_area();
        full.fill(&WHITE)?;
        let root = full.titled(title, (FONT, 30))?;
        let (legend_area, panels_area) =
            root.split_vertically(if break_labels.is_empty() { 60 } else { 90 });
        let styles: Vec<(RGBColor, u32, Dash)> = (0..curves.len()).map(curve_style).collect();
        draw_strip_legend(&legend_area, curves, &styles)?;

        let panels = panels_area.split_evenly((3, 1));
        let bands = [
            ("red", RGBColor(190, 30, 30)),
            ("green", RGBColor(20, 130, 40)),
            ("blue", RGBColor(30, 60, 190)),
        ];
        let breaks: Vec<(f64, &str)> = breaks
            .iter()
            .enumerate()
            .filter(|(_, b)| b.is_finite())
            .map(|(i, &b)| (b, break_labels.get(i).copied().unwrap_or("")))
            .collect();
        for (band, (panel, (name, band_colour))) in panels.iter().zip(bands).enumerate() {
            let ys: Vec<f64> = curves
                .iter()
                .flat_map(|c| samples(c, band))
                .flatten()
                .map(|(_, y)| y)
                .collect();
            let y_range = intensity_range(&ys);
            let last = band == 2;
            let mut chart = ChartBuilder::on(panel)
                .margin_left(20)
                .margin_right(30)
                .margin_top(10)
                .margin_bottom(if last { 10 } else { 0 })
                .x_label_area_size(if last { 70 } else { 30 })
                .y_label_area_size(100)
                .build_cartesian_2d(x_range.clone(), y_range)?;
            let mut mesh = chart.configure_mesh();
            mesh.y_desc(format!("{name} intensity"))
                .axis_desc_style((FONT, 22).into_font().color(&band_colour))
                .label_style((FONT, 16))
                .x_label_formatter(&|v| tick_label(*v))
                .y_label_formatter(&|v| tick_label(*v))
                .y_labels(6)
                .bold_line_style(BLACK.mix(0.12))
                .light_line_style(BLACK.mix(0.0));
            mesh.draw()?;
            if last {
                // By hand: plotters has one style for both axis descriptions, and the y one
                // is in the band's colour.
                let (px, py) = chart.plotting_area().get_pixel_range();
                let style =
                    TextStyle::from((FONT, 22).into_font()).pos(Pos::new(HPos::Center, VPos::Top));
                full.draw(&Text::new(
                    x_label,
                    ((px.start + px.end) / 2, py.end + 40),
                    style,
                ))?;
            }

            let (y_lo, y_hi) = {
                let r = chart.y_range();
                (r.start, r.end)
            };
            for &(b, _) in &breaks {
                if b >= x_range.start && b <= x_range.end {
                    chart.draw_series(DashedLineSeries::new(
                        [(b, y_lo), (b, y_hi)],
                        8,
                        6,
                        BLACK.mix(0.45).stroke_width(2),
                    ))?;
                }
            }
            // Reference last, so the thick black line is on top.
            for (k, c) in curves.iter().enumerate().rev() {
                let (colour, width, dash) = styles[k];
                let style = colour.stroke_width(width);
                for run in samples(c, band).split(|s| s.is_none()) {
                    let run: Vec<(f64, f64)> = run.iter().flatten().copied().collect();
                    if let [single] = run[..] {
                        // No line through one sample: a dot, so that it is not lost.
                        chart.draw_series([Circle::new(single, width + 2, colour.filled())])?;
                        continue;
                    }
                    match dash {
                        Dash::Solid => {
                            chart.draw_series(LineSeries::new(run, style))?;
                        }
                        Dash::Dashed(on, off) => {
                            chart.draw_series(DashedLineSeries::new(run, on, off, style))?;
                        }
                    }
                }
            }
            if band == 0 && !break_labels.is_empty() {
                // Above the top panel, alternating rows when neighbours would collide.
                let font: TextStyle = (FONT, 16).into();
                let mut last_right = [i32::MIN; 2];
                for &(b, text) in &breaks {
                    if text.is_empty() || b < x_range.start || b > x_range.end {
                        continue;
                    }
                    let (x, top) = chart.backend_coord(&(b, y_hi));
                    let (tw, _) = full.estimate_text_size(text, &font)?;
                    let left = x - tw as i32 / 2;
                    let row = if left > last_right[0] + 8 {
                        0
                    } else if left > last_right[1] + 8 {
                        1
                    } else {
                        0
                    };
                    last_right[row] = left + tw as i32;
                    let y = top - 26 - 22 * row as i32;
                    full.draw(&Text::new(text, (left, y), font.clone()))?;
                }
            }
        }
        full.present()?;
    }
    save_png(path, &buf, (w, h))
}

/// Colours that stay apart for common colour-vision deficiencies (Okabe and Ito) and on
/// a grey print, darkened where needed to read against white.
const PALETTE: [RGBColor; 7] = [
    RGBColor(0, 114, 178),   // blue
    RGBColor(213, 94, 0),    // vermillion
    RGBColor(0, 158, 115),   // bluish green
    RGBColor(204, 121, 167), // reddish purple
    RGBColor(230, 159, 0),   // orange
    RGBColor(86, 180, 233),  // sky blue
    RGBColor(160, 140, 0),   // dark yellow
];

const LEGEND_MARGIN: u32 = 10;
const LEGEND_SAMPLE: u32 = 30;

/// Marker `shape` (cycled through six) at `c`, for the groups in the scatter and their
/// legend entries. A small element of its own, so that one type serves every shape.
fn marker<C>(shape: usize, c: C, colour: RGBColor) -> Marker<C> {
    Marker {
        at: c,
        shape: shape % 6,
        colour,
    }
}

struct Marker<C> {
    at: C,
    shape: usize,
    colour: RGBColor,
}

impl<'a, C: 'a> PointCollection<'a, C> for &'a Marker<C> {
    type Point = &'a C;
    type IntoIter = std::iter::Once<&'a C>;
    fn point_iter(self) -> Self::IntoIter {
        std::iter::once(&self.at)
    }
}

impl<C, DB: DrawingBackend> Drawable<DB> for Marker<C> {
    fn draw<I: Iterator<Item = BackendCoord>>(
        &self,
        mut pos: I,
        backend: &mut DB,
        _: (u32, u32),
    ) -> Result<(), DrawingErrorKind<DB::ErrorType>> {
        let Some((x, y)) = pos.next() else {
            return Ok(());
        };
        let fill = self.colour.filled();
        let line = self.colour.stroke_width(2);
        match self.shape {
            0 => backend.draw_circle((x, y), 6, &fill, true),
            1 => backend.fill_polygon([(x, y - 8), (x + 7, y + 5), (x - 7, y + 5)], &fill),
            2 => backend.draw_rect((x - 5, y - 5), (x + 5, y + 5), &fill, true),
            3 => {
                backend.draw_line((x - 6, y - 6), (x + 6, y + 6), &line)?;
                backend.draw_line((x - 6, y + 6), (x + 6, y - 6), &line)
            }
            4 => backend.fill_polygon([(x, y - 7), (x + 7, y), (x, y + 7), (x - 7, y)], &fill),
            _ => backend.draw_circle((x, y), 6, &line, false),
        }
    }
}

#[derive(Debug, Clone, Copy)]
enum Dash {
    Solid,
    Dashed(u32, u32),
}

/// Colour, stroke width and dash pattern of curve `k`; curve 0 is the reference.
fn curve_style(k: usize) -> (RGBColor, u32, Dash) {
    if k == 0 {
        return (BLACK, 4, Dash::Solid);
    }
    let dashes = [
        Dash::Solid,
        Dash::Dashed(14, 8),
        Dash::Dashed(4, 5),
        Dash::Dashed(22, 6),
    ];
    (
        PALETTE[(k - 1) % PALETTE.len()],
        2,
        dashes[(k - 1) % dashes.len()],
    )
}

/// One-row legend (wrapping when it gets too wide) naming each curve beside a sample of its line.
fn draw_strip_legend(
    area: &DrawingArea<Canvas<'_>, Shift>,
    curves: &[Curve],
    styles: &[(RGBColor, u32, Dash)],
) -> Result<(), PlotError> {
    let font: TextStyle = (FONT, 18).into();
    let (width, _) = area.dim_in_pixel();
    let (mut x, mut y) = (130i32, 12i32);
    for (c, &(colour, stroke, dash)) in curves.iter().zip(styles) {
        let (tw, th) = area.estimate_text_size(&c.label, &font)?;
        let entry = 50 + tw as i32 + 30;
        if x + entry > width as i32 - 20 && x > 130 {
            x = 130;
            y += th as i32 + 12;
        }
        let mid = y + th as i32 / 2;
        let style = colour.stroke_width(stroke);
        let line = [(x, mid), (x + 40, mid)];
        match dash {
            Dash::Solid => area.draw(&PathElement::new(line, style))?,
            Dash::Dashed(on, off) => area.draw(&DashedPathElement::new(line, on, off, style))?,
        }
        area.draw(&Text::new(
            c.label.as_str(),
            (x + 50, y),
            font.color(&BLACK),
        ))?;
        x += entry;
    }
    Ok(())
}

/// Width and height in pixels of the legend box plotters draws for `lines`.
fn legend_size(lines: &[&str], font: &TextStyle<'_>) -> Result<(i32, i32), PlotError> {
    let mut text = MultiLineText::<(i32, i32), &str>::new((0, 0), font.clone());
    for line in lines {
        text.push_line(*line);
    }
    let (w, h) = text
        .estimate_dimension()
        .map_err(|e| PlotError::Draw(e.to_string()))?;
    let m = LEGEND_MARGIN as i32;
    Ok((w + LEGEND_SAMPLE as i32 + 2 * m, h + 2 * m))
}

#[derive(Debug, Clone, Copy)]
struct Rect {
    x: i32,
    y: i32,
    w: i32,
    h: i32,
}

impl Rect {
    fn new(x: i32, y: i32, w: i32, h: i32) -> Self {
        Rect { x, y, w, h }
    }
    fn around(x: i32, y: i32, r: i32) -> Self {
        Rect::new(x - r, y - r, 2 * r, 2 * r)
    }
    fn overlaps(&self, o: &Rect) -> bool {
        self.x < o.x + o.w && o.x < self.x + self.w && self.y < o.y + o.h && o.y < self.y + self.h
    }
    fn contains(&self, o: &Rect) -> bool {
        o.x >= self.x
            && o.y >= self.y
            && o.x + o.w <= self.x + self.w
            && o.y + o.h <= self.y + self.h
    }
}

/// Log-axis range around positive values, widened by a fifth of a decade each side (a whole
/// decade each side when all values are equal).
fn log_range(values: &[f64]) -> std::ops::Range<f64> {
    let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let pad = if hi > lo { 10f64.powf(0.2) } else { 10.0 };
    lo / pad..hi * pad
}

/// The range of `values` (widened by 0.5 each side when they are all equal).
fn linear_range(values: &[f64]) -> std::ops::Range<f64> {
    let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if hi > lo {
        lo..hi
    } else {
        lo - 0.5..hi + 0.5
    }
}

/// Intensity axis: from 0 (or the lowest value when negative) to 8% above the highest value.
fn intensity_range(values: &[f64]) -> std::ops::Range<f64> {
    let lo = values.iter().copied().fold(0.0, f64::min);
    let hi = values.iter().copied().fold(0.0, f64::max);
    if hi > lo {
        lo..hi + 0.08 * (hi - lo)
    } else {
        lo..lo + 1.0
    }
}

/// Tick text: plain decimals from 0.001 up to 10^4, otherwise like `2.5e-7`, both with at
/// most three significant digits and no trailing zeros.
fn tick_label(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let mag = v.abs().log10().floor() as i32;
    if (-3..4).contains(&mag) {
        let decimals = (2 - mag).max(0) as usize;
        trim_zeros(&format!("{v:.decimals$}")).to_string()
    } else {
        let s = format!("{v:.2e}");
        let (mantissa, exponent) = s.split_once('e').unwrap_or((&s, "0"));
        format!("{}e{exponent}", trim_zeros(mantissa))
    }
}

fn trim_zeros(s: &str) -> &str {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        s
    }
}

/// Registers the embedded DejaVu Sans under [`FONT`] once per process.
fn register_font() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).is_ok()
            && plotters::style::register_font(FONT, FontStyle::Bold, dejavu::sans::bold()).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(PlotError::Font)
    }
}

fn save_png(path: &Path, rgb: &[u8], (w, h): (u32, u32)) -> Result<(), PlotError> {
    image::save_buffer_with_format(
        path,
        rgb,
        w,
        h,
        image::ColorType::Rgb8,
        image::ImageFormat::Png,
    )
    .map_err(|source| PlotError::Write {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(label: &str, group: &str, time_s: f64, error: f64) -> Point {
        Point {
            label: label.to_string(),
            group: group.to_string(),
            time_s,
            error,
        }
    }

    fn pts(te: &[(f64, f64)]) -> Vec<Point> {
        te.iter()
            .enumerate()
            .map(|(i, &(t, e))| pt(&format!("p{i}"), "g", t, e))
            .collect()
    }

    /// The definition, checked against every other point.
    fn front_by_definition(points: &[Point]) -> Vec<usize> {
        let ok = |p: &Point| !p.time_s.is_nan() && !p.error.is_nan();
        let mut front: Vec<usize> = (0..points.len())
            .filter(|&i| ok(&points[i]))
            .filter(|&i| {
                let p = &points[i];
                !points.iter().any(|q| {
                    ok(q)
                        && q.time_s <= p.time_s
                        && q.error <= p.error
                        && (q.time_s < p.time_s || q.error < p.error)
                })
            })
            .collect();
        front.sort_by(|&a, &b| {
            let (pa, pb) = (&points[a], &points[b]);
            pa.time_s
                .total_cmp(&pb.time_s)
                .then(pa.error.total_cmp(&pb.error))
                .then(a.cmp(&b))
        });
        front
    }

    #[test]
    fn pareto_front_hand_made_cases() {
        assert_eq!(pareto_front(&[]), Vec::<usize>::new());
        assert_eq!(pareto_front(&pts(&[(1.0, 1.0)])), vec![0]);
        // Dominated in both, and in one with a tie in the other.
        assert_eq!(pareto_front(&pts(&[(2.0, 2.0), (1.0, 1.0)])), vec![1]);
        assert_eq!(pareto_front(&pts(&[(1.0, 2.0), (1.0, 1.0)])), vec![1]);
        assert_eq!(pareto_front(&pts(&[(2.0, 1.0), (1.0, 1.0)])), vec![1]);
        // Exact duplicates do not dominate each other.
        assert_eq!(
            pareto_front(&pts(&[(1.0, 1.0), (3.0, 3.0), (1.0, 1.0)])),
            vec![0, 2]
        );
        // A trade-off: all three on the front, returned in time order; (3, 3) is dominated.
        assert_eq!(
            pareto_front(&pts(&[(4.0, 0.5), (3.0, 3.0), (1.0, 4.0), (2.0, 1.0)])),
            vec![2, 3, 0]
        );
        // NaN is left out; zero and negative values are ordinary numbers here.
        assert_eq!(
            pareto_front(&pts(&[
                (f64::NAN, 0.0),
                (1.0, f64::NAN),
                (2.0, 0.0),
                (3.0, -1.0)
            ])),
            vec![2, 3]
        );
    }

    #[test]
    fn pareto_front_matches_its_definition() {
        // Small integer grids, so that ties in time, in error and in both are common.
        let mut state = 12345u64;
        let mut next = |n: u64| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) % n
        };
        for _ in 0..500 {
            let len = next(12) as usize;
            let points: Vec<Point> = (0..len)
                .map(|i| {
                    let t = if next(20) == 0 {
                        f64::NAN
                    } else {
                        next(6) as f64
                    };
                    pt(&format!("p{i}"), "g", t, next(6) as f64)
                })
                .collect();
            assert_eq!(
                pareto_front(&points),
                front_by_definition(&points),
                "{points:?}"
            );
        }
    }

    /// Decodes the PNG and returns it with the number of distinct colours in it.
    fn decode(path: &Path) -> (image::RgbImage, usize) {
        let img = image::open(path).expect("the plot is a PNG").to_rgb8();
        let mut colours: Vec<[u8; 3]> = img.pixels().map(|p| p.0).collect();
        colours.sort_unstable();
        colours.dedup();
        let n = colours.len();
        (img, n)
    }

    /// Pixels darker than mid-grey in rows `rows`, over the middle half of the width.
    fn dark_pixels(img: &image::RgbImage, rows: std::ops::Range<u32>) -> usize {
        let w = img.width();
        rows.flat_map(|y| (w / 4..3 * w / 4).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let [r, g, b] = img.get_pixel(x, y).0;
                u32::from(r) + u32::from(g) + u32::from(b) < 3 * 100
            })
            .count()
    }

    fn demo_points() -> Vec<Point> {
        let mut points = Vec::new();
        for (g, group) in ["a", "b", "c", "d", "e", "f", "g"].iter().enumerate() {
            for k in 0..4 {
                let time_s = 0.01 * 3f64.powi(k) * (1.0 + g as f64 / 7.0);
                let error = 0.3 / (1.0 + k as f64 * (g as f64 + 1.0)).powi(2);
                points.push(pt(&format!("{group}{k}"), group, time_s, error));
            }
        }
        points
    }

    #[test]
    fn error_vs_time_writes_a_png_with_text() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("e.png");
        let points = demo_points();
        error_vs_time(&path, "Error versus time", "time (s)", "error", &points).unwrap();
        let (img, colours) = decode(&path);
        assert_eq!(img.dimensions(), ERROR_VS_TIME_SIZE);
        // Seven group colours, black, white, grid greys and anti-aliased text.
        assert!(colours > 50, "only {colours} colours");
        // The title (and only the title) is in the top 50 rows.
        assert!(dark_pixels(&img, 0..50) > 200, "no title text");
        let untitled = dir.path().join("untitled.png");
        error_vs_time(&untitled, "", "time (s)", "error", &points).unwrap();
        let (img, _) = decode(&untitled);
        assert_eq!(dark_pixels(&img, 0..50), 0);
    }

    #[test]
    fn error_vs_time_handles_degenerate_data() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("e.png");
        let plot = |points: &[Point]| error_vs_time(&path, "t", "x", "y", points);
        assert!(matches!(plot(&[]), Err(PlotError::Empty(_))));
        let nan = [
            pt("n", "g", f64::NAN, 1.0),
            pt("i", "g", 1.0, f64::INFINITY),
        ];
        assert!(matches!(plot(&nan), Err(PlotError::NoFiniteData(_))));
        // One point; all points equal; zero, negative and NaN mixed with ordinary ones.
        plot(&[pt("one", "g", 1.0, 0.1)]).unwrap();
        plot(&[pt("a", "g", 2.0, 0.5), pt("b", "h", 2.0, 0.5)]).unwrap();
        let mixed = [
            pt("zero", "exact", 0.5, 0.0),
            pt("neg", "exact", 0.0, -1e-3),
            pt("nan", "g", 1.0, f64::NAN),
            pt("ok", "g", 0.1, 0.01),
            pt("", "g", 1.0, 0.001),
        ];
        plot(&mixed).unwrap();
        assert_eq!(decode(&path).0.dimensions(), ERROR_VS_TIME_SIZE);
    }

    fn demo_curves() -> Vec<Curve> {
        let x: Vec<f64> = (0..=100).map(|i| f64::from(i) / 50.0).collect();
        let smooth = |x: f64| [0.5 + 0.3 * x.sin(), 0.4 * x, 0.2 + 0.1 * x.cos()];
        vec![
            Curve {
                label: "reference".into(),
                x: x.clone(),
                rgb: x.iter().map(|&x| smooth(x)).collect(),
            },
            Curve {
                label: "steps".into(),
                x: x.clone(),
                rgb: x.iter().map(|&x| smooth((x * 4.0).floor() / 4.0)).collect(),
            },
            Curve {
                label: "biased".into(),
                x: x.clone(),
                rgb: x.iter().map(|&x| smooth(x).map(|v| v * 0.9)).collect(),
            },
        ]
    }

    #[test]
    fn scanline_writes_a_png_with_text() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.png");
        let curves = demo_curves();
        scanline(&path, "Scanline", "x", &curves, &[1.0], &["left | back"]).unwrap();
        let (img, colours) = decode(&path);
        assert_eq!(img.dimensions(), SCANLINE_SIZE);
        assert!(colours > 50, "only {colours} colours");
        assert!(dark_pixels(&img, 0..40) > 100, "no title text");
        let untitled = dir.path().join("untitled.png");
        scanline(&untitled, "", "x", &curves, &[], &[]).unwrap();
        let (img, _) = decode(&untitled);
        assert_eq!(dark_pixels(&img, 0..40), 0);
    }

    #[test]
    fn scanline_handles_degenerate_data() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.png");
        let plot = |curves: &[Curve], breaks: &[f64], labels: &[&str]| {
            scanline(&path, "t", "x", curves, breaks, labels)
        };
        assert!(matches!(plot(&[], &[], &[]), Err(PlotError::Empty(_))));
        let short = Curve {
            label: "short".into(),
            x: vec![0.0, 1.0],
            rgb: vec![[0.0; 3]],
        };
        assert!(matches!(
            plot(&[short], &[], &[]),
            Err(PlotError::CurveLength { x: 2, rgb: 1, .. })
        ));
        assert!(matches!(
            plot(&demo_curves(), &[0.5, 1.0], &["one"]),
            Err(PlotError::BreakLabels {
                breaks: 2,
                labels: 1
            })
        ));
        let nan = Curve {
            label: "nan".into(),
            x: vec![f64::NAN, 1.0],
            rgb: vec![[0.0; 3], [f64::NAN; 3]],
        };
        assert!(matches!(
            plot(std::slice::from_ref(&nan), &[], &[]),
            Err(PlotError::NoFiniteData(_))
        ));
        // Gaps, a single sample, constant zero, an empty curve, breaks off the axis or NaN.
        let mut gappy = demo_curves();
        gappy[1].rgb[10] = [f64::NAN, 0.5, f64::INFINITY];
        gappy[2].x[20] = f64::NAN;
        gappy.push(Curve {
            label: "single".into(),
            x: vec![1.0],
            rgb: vec![[0.2; 3]],
        });
        gappy.push(Curve {
            label: "empty".into(),
            x: vec![],
            rgb: vec![],
        });
        gappy.push(nan);
        plot(&gappy, &[-5.0, f64::NAN, 1.0], &["a", "b", "c"]).unwrap();
        let flat = Curve {
            label: "flat".into(),
            x: vec![1.0, 1.0],
            rgb: vec![[0.0; 3]; 2],
        };
        plot(&[flat], &[1.0], &[]).unwrap();
        assert_eq!(decode(&path).0.dimensions(), SCANLINE_SIZE);
    }

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick_label(0.001), "0.001");
        assert_eq!(tick_label(0.1), "0.1");
        assert_eq!(tick_label(2.5), "2.5");
        assert_eq!(tick_label(1000.0), "1000");
        assert_eq!(tick_label(1e-5), "1e-5");
        assert_eq!(tick_label(2.5e-7), "2.5e-7");
        assert_eq!(tick_label(3e5), "3e5");
        assert_eq!(tick_label(0.0), "0");
    }
}
