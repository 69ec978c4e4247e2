//! Line plots (PNG or SVG) with plotters and a bundled DejaVu Sans font, so that text renders
//! identically on every machine without depending on system fonts.
//!
//! Output is atomic: SVG is rendered into a string and written with [`write_atomic`]; PNG is
//! rendered into a temporary sibling file (with a `.png` extension, which the encoder needs)
//! and renamed over the target.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

use super::atomic::{persist_temp, temp_sibling_path, write_atomic};

/// DejaVu Sans (see `assets/DejaVuSans-LICENSE.txt`).
static FONT_BYTES: &[u8] = include_bytes!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/assets/DejaVuSans.ttf"
));

/// Image size in pixels.
const WIDTH: u32 = 800;
const HEIGHT: u32 = 500;

/// Line colours, cycled when there are more series.
const COLORS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

/// One curve: points `(x[i], y[i])`, joined in order.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub label: String,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
}

/// What to draw: title, axis labels (include units, e.g. "voltage [V]") and the curves.
#[derive(Debug, Clone, Copy)]
pub struct PlotSpec<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub series: &'a [Series],
}

/// Errors of [`line_plot`]. Every message starts with the output path.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("{}: unsupported plot format (the file name must end in .png or .svg)", .path.display())]
    UnsupportedFormat { path: PathBuf },
    #[error("{}: nothing to plot: {reason}", .path.display())]
    NoData { path: PathBuf, reason: String },
    #[error("{}: series '{label}' has {x_len} x values but {y_len} y values", .path.display())]
    LengthMismatch {
        path: PathBuf,
        label: String,
        x_len: usize,
        y_len: usize,
    },
    #[error("{}: data range too large to plot: {reason}", .path.display())]
    Range { path: PathBuf, reason: String },
    #[error("{}: cannot load the bundled font: {reason}", .path.display())]
    Font { path: PathBuf, reason: String },
    #[error("{}: drawing failed: {reason}", .path.display())]
    Drawing { path: PathBuf, reason: String },
    #[error("{}: I/O error: {source}", .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

#[derive(Clone, Copy)]
enum Format {
    Png,
    Svg,
}

/// Draws the series of `spec` as lines into `path` (800×500 px, white background, axis labels,
/// a legend when there is more than one series). The format follows the extension: `.png` or
/// `.svg` (case-insensitive); anything else is an error.
///
/// Non-finite points are skipped. Every series must have `x.len() == y.len() > 0`, and at least
/// one finite point must remain. A constant series or a single point gets a padded range;
/// a series reduced to a single point is drawn as a marker.
pub fn line_plot(path: &Path, spec: &PlotSpec) -> Result<(), PlotError> {
    stacked_plot(path, std::slice::from_ref(spec))
}

/// Draws each spec in its own panel, one above the other (500 px each), on a common x range:
/// e.g. a response and the voltage that drives it. Rules as for [`line_plot`].
pub fn stacked_plot(path: &Path, specs: &[PlotSpec]) -> Result<(), PlotError> {
    stacked_plot_scaled(path, specs, Scale::Linear, &[])
}

/// The scale of an axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    #[default]
    Linear,
    /// Logarithmic: ticks at decades (values ≤ 0 are left out like non-finite ones).
    Log,
}

/// [`stacked_plot`] with the scale of the common x axis and of each panel's y axis (`y_scales[i]`,
/// linear when missing). A logarithmic x axis keeps the unit of its title (a frequency stays in
/// Hz); a logarithmic y axis takes a metric prefix like a linear one.
pub fn stacked_plot_scaled(
    path: &Path,
    specs: &[PlotSpec],
    x_scale_kind: Scale,
    y_scales: &[Scale],
) -> Result<(), PlotError> {
    let format = match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("png") => Format::Png,
        Some("svg") => Format::Svg,
        _ => {
            return Err(PlotError::UnsupportedFormat {
                path: path.to_path_buf(),
            })
        }
    };
    if specs.is_empty() {
        return Err(PlotError::NoData {
            path: path.to_path_buf(),
            reason: "no panel".to_string(),
        });
    }
    let y_kind = |i: usize| y_scales.get(i).copied().unwrap_or_default();
    let mut prepared = Vec::with_capacity(specs.len());
    for (i, spec) in specs.iter().enumerate() {
        prepared.push(prepare(path, spec, x_scale_kind, y_kind(i))?);
    }
    // one x prefix for all panels (they share the x range), one y prefix per panel
    let x_scale = match x_scale_kind {
        Scale::Linear => prefix_scale(
            specs[0].x_label,
            prepared
                .iter()
                .flatten()
                .flat_map(|c| c.points.iter().map(|p| p.0)),
        ),
        Scale::Log => NO_PREFIX,
    };
    let mut labels = Vec::with_capacity(specs.len());
    let mut panels = Vec::with_capacity(specs.len());
    for (i, (spec, mut curves)) in specs.iter().zip(prepared).enumerate() {
        let y_scale = prefix_scale(
            spec.y_label,
            curves.iter().flat_map(|c| c.points.iter().map(|p| p.1)),
        );
        // a logarithmic axis is drawn in log10 of its (prefixed) values
        let log = |v: f64, kind: Scale| match kind {
            Scale::Linear => v,
            Scale::Log => v.log10(),
        };
        for c in &mut curves {
            for p in &mut c.points {
                *p = (
                    log(p.0 * x_scale.factor, x_scale_kind),
                    log(p.1 * y_scale.factor, y_kind(i)),
                );
            }
        }
        labels.push((
            scaled_label(spec.x_label, &x_scale),
            scaled_label(spec.y_label, &y_scale),
        ));
        let r = ranges(path, &curves)?;
        panels.push((curves, r));
    }
    let x_range = panels
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| {
            (a.0.min(p.1 .0 .0), a.1.max(p.1 .0 .1))
        });
    let panels: Vec<Panel> = panels
        .into_iter()
        .zip(specs)
        .zip(&labels)
        .enumerate()
        .map(|(i, (((curves, r), spec), (x, y)))| {
            let (legend, y_range) = place_legend(&curves, x_range, r.1);
            Panel {
                title: spec.title,
                x_label: x,
                y_label: y,
                curves,
                ranges: (r.0, y_range),
                legend,
                log: (x_scale_kind == Scale::Log, y_kind(i) == Scale::Log),
            }
        })
        .collect();
    ensure_font().map_err(|reason| PlotError::Font {
        path: path.to_path_buf(),
        reason,
    })?;
    let drawing_err = |reason: String| PlotError::Drawing {
        path: path.to_path_buf(),
        reason,
    };
    let height = HEIGHT * specs.len() as u32;

    match format {
        Format::Svg => {
            let mut svg = String::new();
            {
                let root = SVGBackend::with_string(&mut svg, (WIDTH, height)).into_drawing_area();
                draw_panels(root, &panels, x_range).map_err(drawing_err)?;
            }
            write_atomic(path, svg.as_bytes()).map_err(|source| PlotError::Io {
                path: path.to_path_buf(),
                source,
            })
        }
        Format::Png => {
            let tmp = temp_sibling_path(path, Some("png")).map_err(|source| PlotError::Io {
                path: path.to_path_buf(),
                source,
            })?;
            // drawn at SUPERSAMPLE× the size and averaged down: anti-aliased lines and text
            let (w, h) = (WIDTH * SUPERSAMPLE, height * SUPERSAMPLE);
            let mut big = vec![255u8; (w * h * 3) as usize];
            {
                let root = BitMapBackend::with_buffer(&mut big, (w, h)).into_drawing_area();
                draw_panels(root, &panels, x_range).map_err(drawing_err)?;
            }
            let small = downsample(&big, WIDTH, height, SUPERSAMPLE);
            let saved = image::save_buffer_with_format(
                &tmp,
                &small,
                WIDTH,
                height,
                image::ColorType::Rgb8,
                image::ImageFormat::Png,
            );
            if let Err(err) = saved {
                let _ = std::fs::remove_file(&tmp);
                return Err(drawing_err(err.to_string()));
            }
            persist_temp(&tmp, path).map_err(|source| PlotError::Io {
                path: path.to_path_buf(),
                source,
            })
        }
    }
}

/// A panel ready to draw: title, axis titles with the units' prefixes, curves in those units and
/// their (x, y) ranges.
struct Panel<'a, 's> {
    title: &'a str,
    x_label: &'a str,
    y_label: &'a str,
    curves: Vec<Curve<'s>>,
    ranges: (Range, Range),
    /// The corner of the legend (drawn when there is more than one curve).
    legend: Corner,
    /// Whether the x and the y axis are logarithmic (values in log10).
    log: (bool, bool),
}

/// Draws the panels top to bottom on the common x range.
fn draw_panels<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    panels: &[Panel],
    x_range: Range,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let k = root.dim_in_pixel().0 / WIDTH;
    let areas = root.split_evenly((panels.len(), 1));
    for (area, panel) in areas.into_iter().zip(panels) {
        draw(area, panel, x_range, k.max(1))?;
    }
    Ok(())
}

/// A series reduced to its finite points, in runs separated where a point is not finite (a
/// gap is left open rather than bridged by a straight line).
struct Curve<'s> {
    label: &'s str,
    points: Vec<(f64, f64)>,
    /// Start index in `points` of every run after the first.
    breaks: Vec<usize>,
}

impl Curve<'_> {
    /// The runs of consecutive finite points.
    fn runs(&self) -> impl Iterator<Item = &[(f64, f64)]> {
        let mut bounds = vec![0];
        bounds.extend(&self.breaks);
        bounds.push(self.points.len());
        bounds
            .windows(2)
            .map(|w| &self.points[w[0]..w[1]])
            .filter(|r| !r.is_empty())
            .collect::<Vec<_>>()
            .into_iter()
    }
}

fn prepare<'s>(
    path: &Path,
    spec: &PlotSpec<'s>,
    x_scale: Scale,
    y_scale: Scale,
) -> Result<Vec<Curve<'s>>, PlotError> {
    // a logarithmic axis has no place for values ≤ 0
    let shown = |v: f64, scale: Scale| v.is_finite() && (scale == Scale::Linear || v > 0.0);
    if spec.series.is_empty() {
        return Err(PlotError::NoData {
            path: path.to_path_buf(),
            reason: "no series".to_string(),
        });
    }
    let mut curves = Vec::with_capacity(spec.series.len());
    for s in spec.series {
        if s.x.len() != s.y.len() {
            return Err(PlotError::LengthMismatch {
                path: path.to_path_buf(),
                label: s.label.clone(),
                x_len: s.x.len(),
                y_len: s.y.len(),
            });
        }
        if s.x.is_empty() {
            return Err(PlotError::NoData {
                path: path.to_path_buf(),
                reason: format!("series '{}' is empty", s.label),
            });
        }
        let mut points = Vec::with_capacity(s.x.len());
        let mut breaks = Vec::new();
        let mut gap = false;
        for (&x, &y) in s.x.iter().zip(&s.y) {
            if shown(x, x_scale) && shown(y, y_scale) {
                if gap && !points.is_empty() {
                    breaks.push(points.len());
                }
                gap = false;
                points.push((x, y));
            } else {
                gap = true;
            }
        }
        curves.push(Curve {
            label: &s.label,
            points,
            breaks,
        });
    }
    if curves.iter().all(|c| c.points.is_empty()) {
        return Err(PlotError::NoData {
            path: path.to_path_buf(),
            reason: "no finite points".to_string(),
        });
    }
    Ok(curves)
}

type Range = (f64, f64);

fn ranges(path: &Path, curves: &[Curve]) -> Result<(Range, Range), PlotError> {
    let bounds = |pick: fn(&(f64, f64)) -> f64| {
        curves
            .iter()
            .flat_map(|c| c.points.iter().map(pick))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            })
    };
    let err = |axis: &str, (lo, hi): Range| PlotError::Range {
        path: path.to_path_buf(),
        reason: format!("{axis} from {lo:e} to {hi:e}"),
    };
    let x = bounds(|p| p.0);
    let y = bounds(|p| p.1);
    let xr = padded(x).ok_or_else(|| err("x", x))?;
    let yr = padded(y).ok_or_else(|| err("y", y))?;
    Ok((xr, yr))
}

/// Widens `[lo, hi]` by 5 % on each side; a degenerate range gets ±10 % of its value (±1 at 0).
/// Returns `None` if the result is not finite.
fn padded((lo, hi): Range) -> Option<Range> {
    let span = hi - lo;
    let pad = if span > 0.0 {
        0.05 * span
    } else if lo != 0.0 {
        0.1 * lo.abs()
    } else {
        1.0
    };
    let (a, b) = (lo - pad, hi + pad);
    (a.is_finite() && b.is_finite() && b - a > 0.0 && (b - a).is_finite()).then_some((a, b))
}

/// A tick value with the round-off of the tick arithmetic removed: a value below 1e-9 of the axis
/// span is zero (a tick at -5.67e-22 on an axis from -1 to 1 is the tick at 0).
fn snap_tick(v: f64, span: f64) -> f64 {
    if span.is_finite() && span > 0.0 && v.abs() <= 1e-9 * span {
        0.0
    } else {
        v
    }
}

/// The label of a tick at `v` on an axis of span `span`: a logarithmic axis (values in log10)
/// labels the decades with their values (1, 10, 100, 1e5) and, when it spans less than two
/// decades, the ticks between them with 3 significant digits; other ticks stay unlabelled.
fn axis_tick(v: f64, span: f64, log: bool) -> String {
    if !log {
        return tick_label(&snap_tick(v, span));
    }
    if (v - v.round()).abs() <= 1e-9 * span.max(1.0) {
        return tick_label(&10f64.powi(v.round() as i32));
    }
    if span < 2.0 {
        let value = 10f64.powf(v);
        let digits = 2 - value.log10().floor() as i32;
        let rounded = (value * 10f64.powi(digits)).round() / 10f64.powi(digits);
        return tick_label(&rounded);
    }
    String::new()
}

/// A corner of the plotting area.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Corner {
    UpperRight,
    UpperLeft,
    LowerRight,
    LowerLeft,
}

/// The legend's size as fractions (width, height) of the plotting area (about 685 × 390 px of
/// a panel): a 14 px font, one row per curve, the sample line and the margins.
fn legend_size(curves: &[Curve]) -> (f64, f64) {
    let chars = curves
        .iter()
        .map(|c| c.label.chars().count())
        .max()
        .unwrap_or(0) as f64;
    let width = 8.0 + 28.0 + 8.5 * chars + 14.0;
    let height = 8.0 + 21.0 * curves.len() as f64 + 12.0;
    (width / 685.0, height / 390.0)
}

/// Where the legend covers no data: the corner (upper right, upper left, lower right, lower left,
/// in that order of preference) whose box holds the fewest points of the curves and of the
/// straight lines between them, and the y range. When every corner covers data the y range is
/// raised at the top to make room for the legend above the curves in the upper right corner.
fn place_legend(curves: &[Curve], x: Range, y: Range) -> (Corner, Range) {
    if curves.len() < 2 {
        return (Corner::UpperRight, y);
    }
    let (w, h) = legend_size(curves);
    // points in fractions of the area, the lines between neighbours sampled
    let mut points = Vec::new();
    for c in curves {
        for run in c.runs() {
            let frac = |p: &(f64, f64)| ((p.0 - x.0) / (x.1 - x.0), (p.1 - y.0) / (y.1 - y.0));
            points.extend(run.iter().map(frac));
            for pair in run.windows(2) {
                let (a, b) = (frac(&pair[0]), frac(&pair[1]));
                let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()) * 100.0).ceil() as usize;
                for k in 1..n.min(1000) {
                    let t = k as f64 / n as f64;
                    points.push((a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1)));
                }
            }
        }
    }
    let covered = |corner: Corner| {
        let (x0, y0) = match corner {
            Corner::UpperRight => (1.0 - w, 1.0 - h),
            Corner::UpperLeft => (0.0, 1.0 - h),
            Corner::LowerRight => (1.0 - w, 0.0),
            Corner::LowerLeft => (0.0, 0.0),
        };
        points
            .iter()
            .filter(|p| p.0 >= x0 && p.0 <= x0 + w && p.1 >= y0 && p.1 <= y0 + h)
            .count()
    };
    let corners = [
        Corner::UpperRight,
        Corner::UpperLeft,
        Corner::LowerRight,
        Corner::LowerLeft,
    ];
    let best = corners
        .into_iter()
        .min_by_key(|&c| covered(c))
        .unwrap_or(Corner::UpperRight);
    if covered(best) == 0 || h >= 0.9 {
        return (best, y);
    }
    // the data's top stays below the legend: the old span takes 1 − h of the new one
    let span = y.1 - y.0;
    (Corner::UpperRight, (y.0, y.0 + span / (1.0 - h)))
}

/// Tick label: up to 10 significant digits, trailing zeros removed; exponent form outside
/// [1e-3, 1e5) so SI values like 2.5e-6 m stay short.
fn tick_label(v: &f64) -> String {
    let v = *v;
    if v == 0.0 {
        return "0".to_string();
    }
    let a = v.abs();
    if (1e-3..1e5).contains(&a) {
        let digits = (9 - a.log10().floor() as i32).clamp(0, 12) as usize;
        let s = format!("{v:.digits$}");
        let s = if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        };
        if s == "-0" {
            "0".to_string()
        } else {
            s
        }
    } else {
        let s = format!("{v:.9e}");
        match s.split_once('e') {
            Some((mantissa, exp)) => {
                let m = mantissa.trim_end_matches('0').trim_end_matches('.');
                format!("{m}e{exp}")
            }
            None => s,
        }
    }
}

fn ensure_font() -> Result<(), String> {
    static REGISTERED: OnceLock<Result<(), String>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            register_font("sans-serif", FontStyle::Normal, FONT_BYTES)
                .map_err(|_| "DejaVuSans.ttf is not a valid font".to_string())
        })
        .clone()
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    panel: &Panel,
    (x0, x1): Range,
    k: u32,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |err: DrawingAreaErrorKind<DB::ErrorType>| err.to_string();
    let px = |v: u32| v * k;
    let font = |size: u32| ("sans-serif", f64::from(size * k));
    let (y0, y1) = panel.ranges.1;
    root.fill(&WHITE).map_err(e)?;
    let (x_log, y_log) = panel.log;
    let x_tick = |v: &f64| axis_tick(*v, x1 - x0, x_log);
    let y_tick = |v: &f64| axis_tick(*v, y1 - y0, y_log);
    let mut chart = ChartBuilder::on(&root)
        .caption(panel.title, font(22))
        .margin(px(15))
        .x_label_area_size(px(50))
        .y_label_area_size(px(85))
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc(panel.x_label)
        .y_desc(panel.y_label)
        .axis_desc_style(font(17))
        .label_style(font(14))
        .x_label_formatter(&x_tick)
        .y_label_formatter(&y_tick)
        .x_labels(8)
        .y_labels(8)
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(215, 215, 215).stroke_width(k))
        .axis_style(BLACK.stroke_width(k))
        .draw()
        .map_err(e)?;

    for (i, curve) in panel.curves.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        let single = curve.points.len() == 1;
        let style = if single {
            color.filled().stroke_width(px(2))
        } else {
            color.stroke_width(px(2))
        };
        for (n, run) in curve.runs().enumerate() {
            // an isolated point between gaps is drawn as a marker
            let marker = if single || run.len() == 1 { px(4) } else { 0 };
            let style = if run.len() == 1 {
                color.filled().stroke_width(px(2))
            } else {
                style
            };
            let series = LineSeries::new(run.iter().copied(), style).point_size(marker);
            let drawn = chart.draw_series(series).map_err(e)?;
            if n == 0 {
                let len = px(20) as i32;
                drawn
                    .label(curve.label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + len, y)], style));
            }
        }
    }
    if panel.curves.len() > 1 {
        chart
            .configure_series_labels()
            .position(match panel.legend {
                Corner::UpperRight => SeriesLabelPosition::UpperRight,
                Corner::UpperLeft => SeriesLabelPosition::UpperLeft,
                Corner::LowerRight => SeriesLabelPosition::LowerRight,
                Corner::LowerLeft => SeriesLabelPosition::LowerLeft,
            })
            .label_font(font(14))
            .margin(px(8))
            .legend_area_size(px(28))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(e)?;
    }
    root.present().map_err(e)
}

/// Linear size factor of the PNG rendering before it is averaged down (anti-aliasing).
const SUPERSAMPLE: u32 = 3;

/// Averages `k`×`k` blocks of an RGB image `k·width` × `k·height` into one `width` × `height`.
fn downsample(big: &[u8], width: u32, height: u32, k: u32) -> Vec<u8> {
    let (w, h, k) = (width as usize, height as usize, k as usize);
    let stride = w * k * 3;
    let mut out = vec![0u8; w * h * 3];
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let mut sum = 0u32;
                for dy in 0..k {
                    let row = (y * k + dy) * stride;
                    for dx in 0..k {
                        sum += u32::from(big[row + (x * k + dx) * 3 + c]);
                    }
                }
                out[(y * w + x) * 3 + c] = ((sum + (k * k / 2) as u32) / (k * k) as u32) as u8;
            }
        }
    }
    out
}

/// A metric prefix chosen for an axis: the factor its values are multiplied by and the prefix.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Prefix {
    factor: f64,
    symbol: &'static str,
}

const NO_PREFIX: Prefix = Prefix {
    factor: 1.0,
    symbol: "",
};

/// Units written after a metric prefix on plot axes (SI units and their quotients).
const PREFIXABLE: [&str; 15] = [
    "m", "s", "V", "A", "C", "F", "N", "Pa", "J", "W", "Hz", "V/m", "N/m", "C/m²", "Ω",
];

/// The unit in the trailing `[…]` of an axis title, if any.
fn label_unit(label: &str) -> Option<&str> {
    let inner = label.strip_suffix(']')?;
    let open = inner.rfind('[')?;
    Some(&inner[open + 1..])
}

/// The metric prefix (f … T) that brings the largest magnitude of `values` into [1, 1000) when
/// the axis title ends in a prefixable unit such as `[V]`; no prefix otherwise.
fn prefix_scale(label: &str, values: impl Iterator<Item = f64>) -> Prefix {
    // a unit per volt (a gain) takes the prefix on its numerator: m/V → µm/V
    let prefixable = |u: &str| {
        PREFIXABLE.contains(&u)
            || u.strip_suffix("/V")
                .is_some_and(|n| n != "V" && PREFIXABLE.contains(&n))
    };
    if !label_unit(label).is_some_and(prefixable) {
        return NO_PREFIX;
    }
    let largest = values
        .filter(|v| v.is_finite())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    if largest == 0.0 {
        return NO_PREFIX;
    }
    const SYMBOLS: [&str; 10] = ["f", "p", "n", "µ", "m", "", "k", "M", "G", "T"];
    // a hair below a power of 1000 (round-off) still takes the larger prefix
    let e3 = ((largest * (1.0 + 1e-12)).log10() / 3.0).floor() as i32;
    let e3 = e3.clamp(-5, 4);
    Prefix {
        factor: 10f64.powi(-3 * e3),
        symbol: SYMBOLS[(e3 + 5) as usize],
    }
}

/// `label` with its unit given the prefix: "voltage [V]" → "voltage [kV]".
fn scaled_label(label: &str, prefix: &Prefix) -> String {
    match label_unit(label) {
        Some(unit) if !prefix.symbol.is_empty() => {
            let head = &label[..label.len() - unit.len() - 2];
            format!("{head}[{}{unit}]", prefix.symbol)
        }
        _ => label.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fs;

    /// A non-finite value splits a curve into runs: the gap is not bridged by a line.
    #[test]
    fn gaps_split_curves_into_runs() {
        let series = [Series {
            label: "s".to_string(),
            x: vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
            y: vec![1.0, 2.0, f64::NAN, 3.0, f64::NAN, f64::NAN, 4.0],
        }];
        let spec = PlotSpec {
            title: "t",
            x_label: "x",
            y_label: "y",
            series: &series,
        };
        let curves = prepare(Path::new("p.png"), &spec, Scale::Linear, Scale::Linear).unwrap();
        let runs: Vec<Vec<(f64, f64)>> = curves[0].runs().map(<[_]>::to_vec).collect();
        assert_eq!(
            runs,
            vec![
                vec![(0.0, 1.0), (1.0, 2.0)],
                vec![(3.0, 3.0)],
                vec![(6.0, 4.0)]
            ]
        );
    }

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .expect("read dir")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    fn two_series() -> Vec<Series> {
        let v: Vec<f64> = (0..=50).map(|i| i as f64 * 100.0).collect();
        let stretch: Vec<f64> = v.iter().map(|v| 1.0 + 2e-9 * v * v / 5000.0).collect();
        let analytic: Vec<f64> = v.iter().map(|v| 1.0 + 1.9e-9 * v * v / 5000.0).collect();
        vec![
            Series {
                label: "FEM".to_string(),
                x: v.clone(),
                y: stretch,
            },
            Series {
                label: "analytic".to_string(),
                x: v,
                y: analytic,
            },
        ]
    }

    const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A];

    #[test]
    fn png_and_svg_with_two_series() {
        let tmp = tempfile::Builder::new()
            .prefix("deasim-plot-two-")
            .tempdir()
            .unwrap();
        let dir = tmp.path();
        let series = two_series();
        let spec = PlotSpec {
            title: "Stretch versus voltage",
            x_label: "voltage [V]",
            y_label: "stretch λ [-]",
            series: &series,
        };
        let png = dir.join("stretch.png");
        line_plot(&png, &spec).expect("png");
        let bytes = fs::read(&png).expect("read png");
        assert!(bytes.len() > 1000);
        assert_eq!(bytes[..8], PNG_SIGNATURE);
        // Width and height from the IHDR chunk.
        assert_eq!(bytes[16..20], WIDTH.to_be_bytes());
        assert_eq!(bytes[20..24], HEIGHT.to_be_bytes());

        let svg_path = dir.join("stretch.SVG");
        line_plot(&svg_path, &spec).expect("svg");
        let svg = fs::read_to_string(&svg_path).expect("read svg");
        assert!(svg.starts_with("<svg"), "{}", &svg[..svg.len().min(100)]);
        for text in [
            "Stretch versus voltage",
            // 0 … 5000 V is drawn in kV
            "voltage [kV]",
            "stretch λ [-]",
            "FEM",
            "analytic",
        ] {
            assert!(svg.contains(text), "SVG lacks '{text}'");
        }
        assert_eq!(
            entries(dir),
            vec!["stretch.SVG".to_string(), "stretch.png".to_string()]
        );
    }

    #[test]
    fn writes_check_image_for_visual_inspection() {
        let series = two_series();
        let spec = PlotSpec {
            title: "Stretch versus voltage",
            x_label: "voltage [V]",
            y_label: "stretch λ [-]",
            series: &series,
        };
        let tmp = tempfile::Builder::new()
            .prefix("deasim-plot-check-")
            .tempdir()
            .unwrap();
        let path = tmp.path().join("deasim_plot_check.png");
        line_plot(&path, &spec).expect("png");
        assert_eq!(fs::read(&path).expect("read")[..8], PNG_SIGNATURE);
    }

    #[test]
    fn constant_single_point_and_non_finite_series_work() {
        let tmp = tempfile::Builder::new()
            .prefix("deasim-plot-degenerate-")
            .tempdir()
            .unwrap();
        let dir = tmp.path();
        let constant = vec![Series {
            label: "flat".to_string(),
            x: vec![0.0, 1.0, 2.0],
            y: vec![3.5; 3],
        }];
        let single = vec![Series {
            label: "one".to_string(),
            x: vec![0.0],
            y: vec![0.0],
        }];
        let gaps = vec![
            Series {
                label: "gaps".to_string(),
                x: vec![0.0, 1.0, f64::NAN, 3.0, 4.0],
                y: vec![1e-7, f64::INFINITY, 2.0, 3e-7, 2e-7],
            },
            Series {
                label: "all bad".to_string(),
                x: vec![f64::NAN],
                y: vec![1.0],
            },
        ];
        let tiny_span = vec![Series {
            label: "tiny".to_string(),
            x: vec![1.0, 1.0 + f64::EPSILON],
            y: vec![1e300, 1e300 * (1.0 + f64::EPSILON)],
        }];
        for (name, series) in [
            ("constant", &constant),
            ("single", &single),
            ("gaps", &gaps),
            ("tiny", &tiny_span),
        ] {
            let spec = PlotSpec {
                title: name,
                x_label: "x [m]",
                y_label: "y [Pa]",
                series,
            };
            for ext in ["png", "svg"] {
                let path = dir.join(format!("{name}.{ext}"));
                line_plot(&path, &spec).unwrap_or_else(|e| panic!("{name}.{ext}: {e}"));
                assert!(fs::metadata(&path).expect("exists").len() > 0);
            }
        }
    }

    #[test]
    fn bad_input_is_an_error_and_writes_nothing() {
        let tmp = tempfile::Builder::new()
            .prefix("deasim-plot-bad-")
            .tempdir()
            .unwrap();
        let dir = tmp.path();
        let ok = two_series();
        let empty = vec![Series {
            label: "empty".to_string(),
            x: vec![],
            y: vec![],
        }];
        let mismatch = vec![Series {
            label: "mismatch".to_string(),
            x: vec![0.0, 1.0],
            y: vec![0.0],
        }];
        let all_nan = vec![Series {
            label: "nan".to_string(),
            x: vec![f64::NAN, 1.0],
            y: vec![0.0, f64::NAN],
        }];
        let huge = vec![Series {
            label: "huge".to_string(),
            x: vec![-f64::MAX, f64::MAX],
            y: vec![0.0, 1.0],
        }];
        let spec = |series| PlotSpec {
            title: "t",
            x_label: "x",
            y_label: "y",
            series,
        };
        let png = dir.join("out.png");
        let check = |res: Result<(), PlotError>, what: &str| {
            let err = res.expect_err(what);
            let msg = err.to_string();
            assert!(msg.starts_with(&dir.display().to_string()), "{what}: {msg}");
        };
        check(line_plot(&png, &spec(&[])), "no series");
        check(line_plot(&png, &spec(&empty)), "empty series");
        check(line_plot(&png, &spec(&mismatch)), "length mismatch");
        check(line_plot(&png, &spec(&all_nan)), "all non-finite");
        check(line_plot(&png, &spec(&huge)), "huge range");
        assert!(matches!(
            line_plot(&png, &spec(&empty)),
            Err(PlotError::NoData { .. })
        ));
        check(line_plot(&dir.join("out.pdf"), &spec(&ok)), "pdf");
        check(line_plot(&dir.join("out"), &spec(&ok)), "no extension");
        assert!(matches!(
            line_plot(&dir.join("out.jpg"), &spec(&ok)),
            Err(PlotError::UnsupportedFormat { .. })
        ));
        let missing = dir.join("no-such-dir").join("out.png");
        assert!(line_plot(&missing, &spec(&ok)).is_err());
        let missing = dir.join("no-such-dir").join("out.svg");
        assert!(matches!(
            line_plot(&missing, &spec(&ok)),
            Err(PlotError::Io { .. })
        ));
        assert!(entries(dir).is_empty(), "{:?}", entries(dir));
    }

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick_label(&0.0), "0");
        assert_eq!(tick_label(&-0.0), "0");
        assert_eq!(tick_label(&0.30000000000000004), "0.3");
        assert_eq!(tick_label(&1500.0), "1500");
        assert_eq!(tick_label(&-2.5), "-2.5");
        assert_eq!(tick_label(&2.5e-6), "2.5e-6");
        assert_eq!(tick_label(&1.0e6), "1e6");
        assert_eq!(tick_label(&1.000_000_1), "1.0000001");
    }

    #[test]
    fn axes_take_the_metric_prefix_of_their_largest_value() {
        let pick = |label: &str, v: &[f64]| {
            let p = prefix_scale(label, v.iter().copied());
            (scaled_label(label, &p), p.factor)
        };
        assert_eq!(
            pick("voltage [V]", &[0.0, 2500.0]),
            ("voltage [kV]".into(), 1e-3)
        );
        assert_eq!(pick("deflection [m]", &[-3e-4, 1e-5]).0, "deflection [µm]");
        assert_eq!(pick("deflection [m]", &[1e-3]).0, "deflection [mm]");
        assert_eq!(
            pick("capacitance [F]", &[4e-11, f64::NAN]).0,
            "capacitance [pF]"
        );
        assert_eq!(pick("field [V/m]", &[6e7]).0, "field [MV/m]");
        assert_eq!(pick("stress [Pa]", &[999.0]), ("stress [Pa]".into(), 1.0));
        // a value a hair below 1000 by round-off takes the larger prefix
        assert_eq!(
            pick("voltage [V]", &[999.999_999_999_999_9]).0,
            "voltage [kV]"
        );
        // dimensionless, unknown units, zero data and titles without a unit stay as they are
        assert_eq!(pick("stretch [-]", &[1e-6]), ("stretch [-]".into(), 1.0));
        assert_eq!(pick("x [furlong]", &[1e6]).0, "x [furlong]");
        assert_eq!(pick("voltage [V]", &[0.0, 0.0]).0, "voltage [V]");
        assert_eq!(
            pick("log10(frequency / Hz)", &[0.001]).0,
            "log10(frequency / Hz)"
        );
        // out of the prefix range: the nearest prefix
        assert_eq!(pick("charge [C]", &[1e-20]).0, "charge [fC]");
    }

    #[test]
    fn png_is_averaged_down_from_the_supersampled_drawing() {
        // 2×2 blocks of a 4×2 RGB image: black/white halves average to grey
        let big = [
            0, 0, 0, 255, 255, 255, 10, 10, 10, 10, 10, 10, //
            255, 255, 255, 0, 0, 0, 10, 10, 10, 10, 10, 10,
        ];
        assert_eq!(downsample(&big, 2, 1, 2), vec![128, 128, 128, 10, 10, 10]);
    }

    /// The points of `curves` inside the legend's box at `corner` for the ranges `x`, `y`.
    fn under_legend(curves: &[Curve], corner: Corner, x: Range, y: Range) -> usize {
        let (w, h) = legend_size(curves);
        let (x0, y0) = match corner {
            Corner::UpperRight => (1.0 - w, 1.0 - h),
            Corner::UpperLeft => (0.0, 1.0 - h),
            Corner::LowerRight => (1.0 - w, 0.0),
            Corner::LowerLeft => (0.0, 0.0),
        };
        curves
            .iter()
            .flat_map(|c| c.points.iter())
            .map(|p| ((p.0 - x.0) / (x.1 - x.0), (p.1 - y.0) / (y.1 - y.0)))
            .filter(|p| p.0 >= x0 && p.0 <= x0 + w && p.1 >= y0 && p.1 <= y0 + h)
            .count()
    }

    /// The legend goes to a corner without data: the load–unload loops of a cyclic material test
    /// (`deasim material --test cyclic`) reach into the upper right corner, not the upper left;
    /// when every corner holds data the y range grows so that the legend sits above the curves.
    #[test]
    fn the_legend_covers_no_data() {
        // three loops from (1, 0) up to (2.5, 40…60 kPa) and back down to (1, −15…−30 kPa)
        let series: Vec<Series> = [43e3, 55e3, 62e3]
            .iter()
            .enumerate()
            .map(|(k, &peak)| {
                let up = (0..=50).map(|i| i as f64 / 50.0);
                let down = (0..=50).map(|i| 1.0 - i as f64 / 50.0);
                let mut x = Vec::new();
                let mut y = Vec::new();
                for s in up {
                    x.push(1.0 + 1.5 * s);
                    y.push(peak * s.powf(0.3));
                }
                let low = -15e3 - 7e3 * k as f64;
                for s in down {
                    x.push(1.0 + 1.5 * s);
                    y.push(low + (peak - low) * s.powi(2));
                }
                Series {
                    label: format!("0.0{} 1/s", 2 * k + 1),
                    x,
                    y,
                }
            })
            .collect();
        let spec = PlotSpec {
            title: "t",
            x_label: "stretch λ [-]",
            y_label: "nominal stress P₁₁ [Pa]",
            series: &series,
        };
        let curves = prepare(Path::new("p.png"), &spec, Scale::Linear, Scale::Linear).unwrap();
        let (x, y) = ranges(Path::new("p.png"), &curves).unwrap();
        assert!(under_legend(&curves, Corner::UpperRight, x, y) > 0);
        let (corner, y2) = place_legend(&curves, x, y);
        assert_eq!(y2, y);
        assert_ne!(corner, Corner::UpperRight);
        assert_eq!(under_legend(&curves, corner, x, y2), 0);
        // data in every corner: room is made at the top
        let full = [
            Series {
                label: "a".into(),
                x: vec![0.0, 1.0, 0.0, 1.0],
                y: vec![0.0, 0.0, 1.0, 1.0],
            },
            Series {
                label: "b".into(),
                x: vec![0.5],
                y: vec![0.5],
            },
        ];
        let spec = PlotSpec {
            series: &full,
            ..spec
        };
        let curves = prepare(Path::new("p.png"), &spec, Scale::Linear, Scale::Linear).unwrap();
        let (x, y) = ranges(Path::new("p.png"), &curves).unwrap();
        let (corner, y2) = place_legend(&curves, x, y);
        assert_eq!(corner, Corner::UpperRight);
        assert!(y2.1 > y.1 && y2.0 == y.0);
        assert_eq!(under_legend(&curves, corner, x, y2), 0);
    }

    /// A logarithmic axis is labelled at its decades with their values, and a gain's unit takes
    /// the prefix of its numerator.
    #[test]
    fn log_axes_label_decades_and_gains_take_prefixes() {
        assert_eq!(axis_tick(2.0, 4.0, true), "100");
        assert_eq!(axis_tick(-7.0, 4.0, true), "1e-7");
        assert_eq!(axis_tick(2.5, 4.0, true), "");
        // less than two decades: the ticks between them too
        assert_eq!(axis_tick(0.5, 1.0, true), "3.16");
        assert_eq!(axis_tick(0.5, 1.0, false), "0.5");
        let p = prefix_scale("|u| per volt [m/V]", [2e-6].into_iter());
        assert_eq!(
            scaled_label("|u| per volt [m/V]", &p),
            "|u| per volt [µm/V]"
        );
        let p = prefix_scale("gain [V/V]", [2e-6].into_iter());
        assert_eq!(p, NO_PREFIX);
        // values ≤ 0 have no place on a logarithmic axis
        let series = [Series {
            label: "s".into(),
            x: vec![1.0, 10.0, 100.0],
            y: vec![1.0, 0.0, 2.0],
        }];
        let spec = PlotSpec {
            title: "t",
            x_label: "f [Hz]",
            y_label: "g [m/V]",
            series: &series,
        };
        let curves = prepare(Path::new("p.png"), &spec, Scale::Log, Scale::Log).unwrap();
        assert_eq!(curves[0].points, vec![(1.0, 1.0), (100.0, 2.0)]);
    }

    #[test]
    fn round_off_ticks_are_zero() {
        assert_eq!(tick_label(&snap_tick(-5.67e-22, 2.0)), "0");
        assert_eq!(tick_label(&snap_tick(3e-19, 1e-6)), "0");
        // a genuinely small value on a small axis stays
        assert_eq!(tick_label(&snap_tick(2.5e-6, 1e-5)), "2.5e-6");
        assert_eq!(snap_tick(-5.67e-22, 0.0), -5.67e-22);
    }
}
