//! Figures: Δ-risk contours (like the paper's Figs. 1–3, 6–8), the obstacle at
//! the mean of its parameters, Monte Carlo "true" contours, and overlays such as a
//! plan's tree and path. A presentation layer: it writes SVG or PNG files with
//! `plotters`, and traces level sets with the `contour` crate (marching squares).
//!
//! The contour of level Δ drawn here is the level set `B(x, t) = Δ` of the
//! floating-point Cantelli bound `B = max_i (E[Pᵢ²] − E[Pᵢ]²)/E[Pᵢ²]` (1 where
//! `E[Pᵢ] > 0`). Figures are illustrations; decisions are never taken from them.

mod font;

use plotters::coord::Shift;
use plotters::prelude::*;
use riskplan_math::contour::cantelli_bound_f64;
use riskplan_scene::Scene;
use std::path::Path;
use thiserror::Error;

/// Why a figure could not be drawn.
#[derive(Debug, Error)]
pub enum VizError {
    /// Output name without `.svg` or `.png`.
    #[error("--out must end in .svg or .png, got '{0}'")]
    Format(String),
    /// The slice options do not leave exactly two axes.
    #[error("{0}")]
    Slice(String),
    /// No TrueType font for labels.
    #[error("{0}")]
    Font(String),
    /// Monte Carlo is impossible (a parameter known only by its moments).
    #[error("{0}")]
    MonteCarlo(String),
    /// The drawing backend failed (for instance, the file cannot be written).
    #[error("drawing failed: {0}")]
    Draw(String),
}

fn draw_err<E: std::fmt::Display>(e: E) -> VizError {
    VizError::Draw(e.to_string())
}

/// What to draw.
#[derive(Clone, Debug)]
pub struct ContourOptions {
    /// Risk levels Δ, one contour each.
    pub deltas: Vec<f64>,
    /// Times (for moving obstacles; one panel colour per time).
    pub times: Vec<f64>,
    /// Fixed coordinates `(axis, value)` for scenes of more than two dimensions.
    pub slices: Vec<(usize, f64)>,
    /// Per entry of `times`, new values of sliced axes at that time (each axis must be
    /// one of `slices`): a section that moves with the time, for instance at a path's
    /// height. The legend names each section's values. Empty: `slices` at every time.
    pub slices_at: Vec<Vec<(usize, f64)>>,
    /// Monte Carlo samples per grid point for the "true" contour, and the seed.
    pub mc: Option<(u64, u64)>,
    /// Grid points per axis for the Cantelli contours.
    pub grid: usize,
    /// Grid points per axis for the Monte Carlo contour (it costs `mc_grid² · samples`).
    pub mc_grid: usize,
    /// Title; defaults to the scene name.
    pub title: Option<String>,
    /// Plot window `(x0, x1, y0, y1)` in the plotted axes; defaults to the workspace.
    pub window: Option<(f64, f64, f64, f64)>,
    /// The bounds whose Δ-contours are drawn (docs/design.md §3.7–§3.10): empty for
    /// Cantelli's alone (the paper's figures); otherwise one curve per entry and Δ, each
    /// in its own colour.
    pub curves: Vec<BoundCurve>,
}

/// One bound's Δ-contour in a figure: outside the curve that bound is at most Δ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BoundCurve {
    /// One bound (Cantelli, zero risk from the support, a moment bound of one order).
    Kind(riskplan_math::contour::BoundKind),
    /// The smallest of them at each point (what `bound: auto` certifies, up to the
    /// sub-interval proofs).
    Best,
}

impl BoundCurve {
    fn label(&self) -> String {
        match self {
            BoundCurve::Kind(k) => k.as_str().to_string(),
            BoundCurve::Best => "best (auto)".into(),
        }
    }
}

impl Default for ContourOptions {
    fn default() -> Self {
        ContourOptions {
            deltas: vec![],
            times: vec![],
            slices: vec![],
            slices_at: vec![],
            mc: None,
            grid: 300,
            mc_grid: 90,
            title: None,
            window: None,
            curves: vec![],
        }
    }
}

/// Something drawn over the contours.
#[derive(Clone, Debug)]
pub enum Overlay {
    /// A polyline in the plotted axes.
    Path {
        /// Points in full scene coordinates (projected onto the plotted axes).
        points: Vec<Vec<f64>>,
        /// RGB colour.
        color: (u8, u8, u8),
        /// Stroke width in pixels.
        width: u32,
        /// Legend label.
        label: Option<String>,
    },
    /// Line segments (a tree), drawn thin.
    Segments {
        /// Pairs of points in scene coordinates.
        segments: Vec<(Vec<f64>, Vec<f64>)>,
        /// RGB colour.
        color: (u8, u8, u8),
        /// Legend label.
        label: Option<String>,
    },
    /// Marked points (start, goal, vertices).
    Points {
        /// Points in scene coordinates.
        points: Vec<Vec<f64>>,
        /// RGB colour.
        color: (u8, u8, u8),
        /// Marker radius in pixels.
        size: u32,
        /// Legend label.
        label: Option<String>,
    },
}

const PALETTE: [(u8, u8, u8); 8] = [
    (200, 30, 30),
    (30, 90, 200),
    (20, 140, 60),
    (160, 60, 170),
    (230, 120, 0),
    (0, 150, 150),
    (120, 80, 40),
    (90, 90, 90),
];

/// The colour of the contours of a figure's `ti`-th time, when it has several times (for
/// overlays that mark the path at those times).
pub fn time_color(ti: usize) -> (u8, u8, u8) {
    PALETTE[ti % PALETTE.len()]
}

/// The two plotted axes and the full-coordinate template for a scene and its slices.
#[derive(Clone)]
struct Axes {
    a: usize,
    b: usize,
    template: Vec<f64>,
}

impl Axes {
    /// The same plotted axes with the sliced coordinates `at` set to new values.
    fn moved(&self, at: &[(usize, f64)]) -> Result<Axes, VizError> {
        let mut ax = self.clone();
        for &(axis, v) in at {
            if axis >= ax.template.len() || axis == ax.a || axis == ax.b {
                return Err(VizError::Slice(format!(
                    "a section at x{} = {v}: x{} is not a sliced axis",
                    axis + 1,
                    axis + 1
                )));
            }
            ax.template[axis] = v;
        }
        Ok(ax)
    }
}

/// Significant digits of the times and section levels printed in legends.
pub const LEGEND_DIGITS: usize = 3;

/// `v` rounded to [`LEGEND_DIGITS`] significant digits, without trailing zeros
/// (`0.7836221802863881` → `0.784`, `1.0` → `1`, `27.456` → `27.5`).
pub fn legend_number(v: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    if v == 0.0 {
        return "0".into();
    }
    let digits = LEGEND_DIGITS as i32;
    let mag = v.abs().log10().floor() as i32;
    let text = if mag >= digits - 1 {
        let unit = 10f64.powi(mag + 1 - digits);
        format!("{:.0}", (v / unit).round() * unit)
    } else {
        let t = format!("{:.*}", (digits - 1 - mag) as usize, v);
        t.trim_end_matches('0').trim_end_matches('.').to_string()
    };
    if text == "-0" {
        "0".into()
    } else {
        text
    }
}

fn axes(scene: &Scene, slices: &[(usize, f64)]) -> Result<Axes, VizError> {
    let mut template = vec![0.0; scene.dim];
    let mut free: Vec<usize> = (0..scene.dim).collect();
    for &(axis, v) in slices {
        if axis >= scene.dim {
            return Err(VizError::Slice(format!("--slice x{}: the scene has only {} dimensions", axis + 1, scene.dim)));
        }
        if !free.contains(&axis) {
            return Err(VizError::Slice(format!("--slice x{} is given twice", axis + 1)));
        }
        template[axis] = v;
        free.retain(|&f| f != axis);
    }
    match free[..] {
        [a, b] => Ok(Axes { a, b, template }),
        _ => Err(VizError::Slice(format!(
            "a {}-D scene needs {} --slice option(s) (e.g. --slice x3=0) to leave two plotted axes",
            scene.dim,
            scene.dim.saturating_sub(2)
        ))),
    }
}

/// A polygon: exterior ring and holes.
type Region = (Vec<(f64, f64)>, Vec<Vec<(f64, f64)>>);

struct Grid {
    n: usize,
    x0: f64,
    y0: f64,
    dx: f64,
    dy: f64,
}

impl Grid {
    fn new(win: (f64, f64, f64, f64), n: usize) -> Self {
        let (x0, x1, y0, y1) = win;
        let n = n.max(8);
        Grid { n, x0, y0, dx: (x1 - x0) / (n - 1) as f64, dy: (y1 - y0) / (n - 1) as f64 }
    }
    fn point(&self, ax: &Axes, i: usize, j: usize, t: f64) -> Vec<f64> {
        let mut p = ax.template.clone();
        p[ax.a] = self.x0 + i as f64 * self.dx;
        p[ax.b] = self.y0 + j as f64 * self.dy;
        p.push(t);
        p
    }
    fn builder(&self) -> contour::ContourBuilder {
        // d3-contour puts sample i at coordinate i + ½ (pixel centres): shift the origin back by half a step.
        contour::ContourBuilder::new(self.n, self.n, true)
            .x_origin(self.x0 - 0.5 * self.dx)
            .y_origin(self.y0 - 0.5 * self.dy)
            .x_step(self.dx)
            .y_step(self.dy)
    }
    /// Polylines of the level set `values = level`.
    fn isolines(&self, values: &[f64], level: f64) -> Vec<Vec<(f64, f64)>> {
        let Ok(lines) = self.builder().lines(values, &[level]) else {
            return vec![];
        };
        lines.iter().flat_map(|l| l.geometry().0.iter().map(|ls| ls.0.iter().map(|c| (c.x, c.y)).collect())).collect()
    }
    /// Polygons (exterior, holes) of the region `values ≥ level`.
    fn regions(&self, values: &[f64], level: f64) -> Vec<Region> {
        let Ok(cs) = self.builder().contours(values, &[level]) else {
            return vec![];
        };
        let mut out = Vec::new();
        for c in &cs {
            for p in c.geometry().0.iter() {
                let ext: Vec<(f64, f64)> = p.exterior().0.iter().map(|c| (c.x, c.y)).collect();
                let holes = p.interiors().iter().map(|ls| ls.0.iter().map(|c| (c.x, c.y)).collect()).collect();
                out.push((ext, holes));
            }
        }
        out
    }
}

/// Max over obstacles of the Cantelli bound on the grid at time `t`.
fn bound_grid(scene: &Scene, ax: &Axes, g: &Grid, t: f64) -> Vec<f64> {
    let mut v = Vec::with_capacity(g.n * g.n);
    for j in 0..g.n {
        for i in 0..g.n {
            let p = g.point(ax, i, j, t);
            v.push(scene.obstacles.iter().map(|o| o.contour.bound_f64(&p)).fold(0.0, f64::max));
        }
    }
    v
}

/// Max over obstacles of one bound (or the best) on the grid at time `t`, in floating point
/// (`certify::piece_bounds::point_bounds_f64`; a bound an obstacle does not have counts as 1).
fn curve_grid(scene: &Scene, ax: &Axes, g: &Grid, t: f64, curve: BoundCurve) -> Vec<f64> {
    let mut v = Vec::with_capacity(g.n * g.n);
    for j in 0..g.n {
        for i in 0..g.n {
            let p = g.point(ax, i, j, t);
            let worst = scene
                .obstacles
                .iter()
                .map(|o| {
                    let each = riskplan_certify::piece_bounds::point_bounds_f64(&o.contour, &p);
                    match curve {
                        BoundCurve::Kind(k) => each.iter().find(|(kk, _)| *kk == k).map_or(1.0, |x| x.1),
                        BoundCurve::Best => each.iter().map(|x| x.1).fold(1.0, f64::min),
                    }
                })
                .fold(0.0, f64::max);
            v.push(worst);
        }
    }
    v
}

/// Max over obstacles of P(x, E[ω], t) on the grid: the obstacle at the mean.
fn mean_obstacle_grid(scene: &Scene, ax: &Axes, g: &Grid, t: f64) -> Vec<f64> {
    let layout = scene.layout();
    let means: Vec<(u16, f64)> = scene
        .params
        .iter()
        .filter_map(|p| p.dist.mean().ok().map(|m| (p.var, riskplan_math::poly::rational_to_f64(&m))))
        .collect();
    let polys: Vec<riskplan_math::poly::Poly<f64>> = scene
        .obstacles
        .iter()
        .map(|o| {
            let mut q = o.poly.map_coeffs(riskplan_math::poly::rational_to_f64);
            // a pedestrian's polynomial is in its own parameters (scene::Pedestrian)
            let own: Vec<(u16, f64)> = o
                .own_params()
                .iter()
                .filter_map(|p| p.dist.mean().ok().map(|m| (p.var, riskplan_math::poly::rational_to_f64(&m))))
                .collect();
            let params = if o.pedestrian.is_some() { &own } else { &means };
            for (v, m) in params {
                q = q.partial_eval(*v, m);
            }
            q
        })
        .collect();
    let mut v = Vec::with_capacity(g.n * g.n);
    let mut vals = vec![0.0; scene.vars.len()];
    for j in 0..g.n {
        for i in 0..g.n {
            let p = g.point(ax, i, j, t);
            vals[..layout.xt_len()].copy_from_slice(&p);
            v.push(polys.iter().map(|q| q.eval(&vals)).fold(f64::NEG_INFINITY, f64::max));
        }
    }
    v
}

/// Max over obstacles of the Monte Carlo estimate of Prob(P ≥ 0) on a grid.
fn mc_grid(scene: &Scene, ax: &Axes, g: &Grid, t: f64, samples: u64, seed: u64) -> Result<Vec<f64>, VizError> {
    let model = scene.mc_model().map_err(|e| VizError::MonteCarlo(format!("--mc: {e}")))?;
    let pts: Vec<Vec<f64>> =
        (0..g.n).flat_map(|j| (0..g.n).map(move |i| (i, j))).map(|(i, j)| g.point(ax, i, j, t)).collect();
    let hits = model.hits(&pts, samples, seed);
    Ok(hits.iter().map(|h| h.iter().copied().max().unwrap_or(0) as f64 / samples as f64).collect())
}

/// Draws the contours of `scene` with `overlays` on top into `out` (`.svg` or `.png`).
pub fn draw(scene: &Scene, opts: &ContourOptions, overlays: &[Overlay], out: &Path) -> Result<(), VizError> {
    let ax = axes(scene, &opts.slices)?;
    if !opts.slices_at.is_empty() && opts.slices_at.len() != opts.times.len() {
        return Err(VizError::Slice(format!(
            "{} sections for {} times: give one per time",
            opts.slices_at.len(),
            opts.times.len()
        )));
    }
    for at in &opts.slices_at {
        ax.moved(at)?;
    }
    font::ensure_registered()?;
    let name = out.to_string_lossy().to_string();
    // Equal scales on both axes (discs look round): size the figure by the window's aspect.
    let (x0, x1, y0, y1) = window(scene, &ax, opts);
    let aspect = ((y1 - y0) / (x1 - x0)).clamp(0.3, 2.5);
    let plot_w = 800.0;
    let size = (plot_w as u32 + 80, (plot_w * aspect) as u32 + 110);
    if name.ends_with(".svg") {
        let root = SVGBackend::new(out, size).into_drawing_area();
        render(scene, opts, overlays, &ax, root)
    } else if name.ends_with(".png") {
        let root = BitMapBackend::new(out, size).into_drawing_area();
        render(scene, opts, overlays, &ax, root)
    } else {
        Err(VizError::Format(name))
    }
}

fn window(scene: &Scene, ax: &Axes, opts: &ContourOptions) -> (f64, f64, f64, f64) {
    opts.window.unwrap_or((
        scene.workspace.lower[ax.a],
        scene.workspace.upper[ax.a],
        scene.workspace.lower[ax.b],
        scene.workspace.upper[ax.b],
    ))
}

fn rgb((r, g, b): (u8, u8, u8)) -> RGBColor {
    RGBColor(r, g, b)
}

fn project(ax: &Axes, p: &[f64]) -> (f64, f64) {
    (p.get(ax.a).copied().unwrap_or(0.0), p.get(ax.b).copied().unwrap_or(0.0))
}

fn render<DB: DrawingBackend>(
    scene: &Scene,
    opts: &ContourOptions,
    overlays: &[Overlay],
    ax: &Axes,
    root: DrawingArea<DB, Shift>,
) -> Result<(), VizError>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(draw_err)?;
    let win = window(scene, ax, opts);
    let (lx, ux, ly, uy) = win;
    let title = opts.title.clone().unwrap_or_else(|| {
        let slices: Vec<String> = opts.slices.iter().map(|(a, v)| format!("x{}={v}", a + 1)).collect();
        if !opts.slices_at.is_empty() {
            format!("{} (a section per time: see the legend)", scene.name)
        } else if slices.is_empty() {
            scene.name.clone()
        } else {
            format!("{} ({})", scene.name, slices.join(", "))
        }
    });
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 24))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(lx..ux, ly..uy)
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .x_desc(format!("x{}", ax.a + 1))
        .y_desc(format!("x{}", ax.b + 1))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(draw_err)?;
    let g = Grid::new(win, opts.grid);
    let multi_time = opts.times.len() > 1;
    // each time's axes (its section)
    let panels: Vec<Axes> = (0..opts.times.len())
        .map(|ti| opts.slices_at.get(ti).map_or(Ok(ax.clone()), |at| ax.moved(at)))
        .collect::<Result<_, _>>()?;
    let layers = Layers { scene, opts, panels, grid: g, win, multi_time };
    // bottom to top: the Monte Carlo "true" contours, the obstacles at E[ω], the Δ-contours
    layers.monte_carlo(&mut chart)?;
    layers.mean_obstacles(&mut chart)?;
    if opts.curves.is_empty() {
        layers.cantelli(&mut chart)?;
    } else {
        layers.bound_curves(&mut chart)?;
    }
    // 4. Overlays.
    for o in overlays {
        draw_overlay(&mut chart, ax, o)?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.4))
        .label_font(("sans-serif", 14))
        .position(SeriesLabelPosition::UpperLeft)
        .draw()
        .map_err(draw_err)?;
    root.present().map_err(draw_err)?;
    Ok(())
}

/// What the layers of a contour figure are drawn from: the scene, the options, each
/// time's axes (its section), the evaluation grid and window.
struct Layers<'a> {
    scene: &'a Scene,
    opts: &'a ContourOptions,
    panels: Vec<Axes>,
    grid: Grid,
    win: (f64, f64, f64, f64),
    multi_time: bool,
}

impl Layers<'_> {
    /// The words naming time `ti` in the legend: its time (when the times differ) and
    /// its section.
    fn panel_label(&self, ti: usize) -> String {
        let opts = self.opts;
        let times_differ = opts.times.windows(2).any(|w| w[0] != w[1]);
        let mut parts = Vec::new();
        if times_differ {
            parts.push(format!("t={}", legend_number(opts.times[ti])));
        }
        for &(a, v) in opts.slices_at.get(ti).map_or(&[][..], |at| &at[..]) {
            parts.push(format!("x{}={}", a + 1, legend_number(v)));
        }
        parts.join(", ")
    }

    /// The Monte Carlo "true" contours (with `--mc`): the largest true region shaded, each Δ's contour a thin line.
    fn monte_carlo<DB: DrawingBackend>(&self, chart: &mut Chart<'_, DB>) -> Result<(), VizError>
    where
        DB::ErrorType: 'static,
    {
        let (scene, opts, panels, win, multi_time) = (self.scene, self.opts, &self.panels, self.win, self.multi_time);
        if let Some((samples, seed)) = opts.mc {
            let mg = Grid::new(win, opts.mc_grid);
            for (ti, &t) in opts.times.iter().enumerate() {
                let est = mc_grid(scene, &panels[ti], &mg, t, samples, seed)?;
                // Shade the largest true region (smallest Δ): where the estimated risk exceeds it.
                let dmin = opts.deltas.iter().copied().fold(f64::INFINITY, f64::min);
                let shade = RGBColor(60, 170, 90).mix(0.25);
                for (ext, holes) in mg.regions(&est, dmin + f64::EPSILON) {
                    chart.draw_series(std::iter::once(Polygon::new(ext, shade.filled()))).map_err(draw_err)?;
                    for h in holes {
                        chart.draw_series(std::iter::once(Polygon::new(h, WHITE.filled()))).map_err(draw_err)?;
                    }
                }
                // Each Δ's true contour as a thin line in that Δ's colour.
                for (di, &d) in opts.deltas.iter().enumerate() {
                    let color = rgb(PALETTE[(if multi_time { ti } else { di }) % PALETTE.len()]);
                    let mut first = true;
                    for line in mg.isolines(&est, d + f64::EPSILON) {
                        let s = chart
                            .draw_series(LineSeries::new(line, ShapeStyle::from(color.mix(0.8)).stroke_width(1)))
                            .map_err(draw_err)?;
                        if first && ti == 0 && di == 0 {
                            let label = format!(
                                "Monte Carlo true contours, thin ({samples} samples/point); shaded: risk > {dmin}"
                            );
                            s.label(label).legend(|(x, y)| {
                                Rectangle::new([(x, y - 5), (x + 18, y + 5)], RGBColor(60, 170, 90).mix(0.4).filled())
                            });
                        }
                        first = false;
                    }
                }
            }
        }
        Ok(())
    }

    /// The obstacles at the mean of their parameters, filled grey; when the Cantelli contours are coloured by time, in their time's colour.
    fn mean_obstacles<DB: DrawingBackend>(&self, chart: &mut Chart<'_, DB>) -> Result<(), VizError>
    where
        DB::ErrorType: 'static,
    {
        let (scene, opts, panels, g, multi_time) = (self.scene, self.opts, &self.panels, &self.grid, self.multi_time);
        let by_time = multi_time && opts.curves.is_empty();
        let fill = |ti: usize, alpha: f64| {
            if by_time {
                rgb(PALETTE[ti % PALETTE.len()]).mix(alpha * 0.8)
            } else {
                RGBColor(90, 90, 90).mix(alpha)
            }
        };
        let mut first = true;
        for (ti, &t) in opts.times.iter().enumerate() {
            let mean = mean_obstacle_grid(scene, &panels[ti], g, t);
            for (ext, holes) in g.regions(&mean, 0.0) {
                let s =
                    chart.draw_series(std::iter::once(Polygon::new(ext, fill(ti, 0.35).filled()))).map_err(draw_err)?;
                if first {
                    let swatch = fill(ti, 0.5);
                    let label = if by_time { "obstacle at E[ω], in its time's colour" } else { "obstacle at E[ω]" };
                    s.label(label).legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 18, y + 5)], swatch.filled()));
                    first = false;
                }
                for h in holes {
                    chart.draw_series(std::iter::once(Polygon::new(h, WHITE.mix(0.9).filled()))).map_err(draw_err)?;
                }
            }
        }
        Ok(())
    }

    /// The Δ-contours of each bound asked for (`--bounds`), one colour per bound.
    fn bound_curves<DB: DrawingBackend>(&self, chart: &mut Chart<'_, DB>) -> Result<(), VizError>
    where
        DB::ErrorType: 'static,
    {
        let (scene, opts, panels, g) = (self.scene, self.opts, &self.panels, &self.grid);
        for (ti, &t) in opts.times.iter().enumerate() {
            for (ci, &curve) in opts.curves.iter().enumerate() {
                let b = curve_grid(scene, &panels[ti], g, t, curve);
                let color = rgb(PALETTE[ci % PALETTE.len()]);
                let width = if curve == BoundCurve::Best { 3 } else { 2 };
                for (di, &d) in opts.deltas.iter().enumerate() {
                    let mut first = ti == 0 && di == 0;
                    for line in g.isolines(&b, d) {
                        let s = chart
                            .draw_series(LineSeries::new(line, ShapeStyle::from(color).stroke_width(width)))
                            .map_err(draw_err)?;
                        if first {
                            s.label(format!("{} Δ-contour", curve.label())).legend(move |(x, y)| {
                                PathElement::new(vec![(x, y), (x + 18, y)], ShapeStyle::from(color).stroke_width(width))
                            });
                            first = false;
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// Cantelli's Δ-contours (the inner approximations of eqs. 10, 12): the level sets B = Δ, one colour per Δ (per time, when there are several).
    fn cantelli<DB: DrawingBackend>(&self, chart: &mut Chart<'_, DB>) -> Result<(), VizError>
    where
        DB::ErrorType: 'static,
    {
        let (scene, opts, panels, g, multi_time) = (self.scene, self.opts, &self.panels, &self.grid, self.multi_time);
        for (ti, &t) in opts.times.iter().enumerate() {
            let b = bound_grid(scene, &panels[ti], g, t);
            let which = self.panel_label(ti);
            for (di, &d) in opts.deltas.iter().enumerate() {
                let color = rgb(PALETTE[(if multi_time { ti } else { di }) % PALETTE.len()]);
                let label = if which.is_empty() {
                    format!("Cantelli contour Δ={d}")
                } else {
                    format!("Cantelli contour Δ={d}, {which}")
                };
                let mut first = true;
                for line in g.isolines(&b, d) {
                    let s = chart
                        .draw_series(LineSeries::new(line, ShapeStyle::from(color).stroke_width(2)))
                        .map_err(draw_err)?;
                    if first && (!multi_time || di == 0) {
                        s.label(label.clone()).legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 18, y)], ShapeStyle::from(color).stroke_width(2))
                        });
                        first = false;
                    }
                }
            }
        }
        Ok(())
    }
}

type Chart<'a, DB> =
    ChartContext<'a, DB, Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>>;

fn draw_overlay<DB: DrawingBackend>(chart: &mut Chart<'_, DB>, ax: &Axes, o: &Overlay) -> Result<(), VizError>
where
    DB::ErrorType: 'static,
{
    match o {
        Overlay::Path { points, color, width, label } => {
            let c = rgb(*color);
            let w = *width;
            let s = chart
                .draw_series(LineSeries::new(
                    points.iter().map(|p| project(ax, p)),
                    ShapeStyle::from(c).stroke_width(w),
                ))
                .map_err(draw_err)?;
            if let Some(l) = label {
                s.label(l).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], ShapeStyle::from(c).stroke_width(w))
                });
            }
        }
        Overlay::Segments { segments, color, label } => {
            let c = rgb(*color).mix(0.6);
            let s = chart
                .draw_series(segments.iter().map(|(a, b)| {
                    PathElement::new(vec![project(ax, a), project(ax, b)], ShapeStyle::from(c).stroke_width(1))
                }))
                .map_err(draw_err)?;
            if let Some(l) = label {
                s.label(l).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], ShapeStyle::from(c).stroke_width(1))
                });
            }
        }
        Overlay::Points { points, color, size, label } => {
            let c = rgb(*color);
            let r = *size;
            let s = chart
                .draw_series(points.iter().map(|p| Circle::new(project(ax, p), r, c.filled())))
                .map_err(draw_err)?;
            if let Some(l) = label {
                s.label(l).legend(move |(x, y)| Circle::new((x + 9, y), r, c.filled()));
            }
        }
    }
    Ok(())
}

/// The plain Cantelli bound helper re-exported for figure code.
pub fn bound(mean: f64, second: f64) -> f64 {
    cantelli_bound_f64(mean, second)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legend_numbers_have_three_significant_digits() {
        for (v, s) in [
            (0.0, "0"),
            (-0.0, "0"),
            (1.0, "1"),
            (0.5, "0.5"),
            (0.7836221802863881, "0.784"),
            (0.22656289844485455, "0.227"),
            (0.9996, "1"),
            (27.456, "27.5"),
            (1234.5, "1230"),
            (-0.48213, "-0.482"),
            (0.000123456, "0.000123"),
        ] {
            assert_eq!(legend_number(v), s, "{v}");
        }
    }
}
