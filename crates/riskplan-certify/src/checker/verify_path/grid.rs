//! The grid of the box tests (`NearGrid`): per cell of the workspace, the obstacles its box tests do not clear.

use super::*;

/// The final check's own spatial filter on crowded scenes (docs/design.md §5.12): a grid of
/// cells over the workspace and, per cell, the obstacles its box test (`Near::clears`)
/// does not clear over the whole cell and the whole horizon. A piece whose parts' hulls lie
/// in cells where an obstacle is cleared is safe from it at every point and time (each point
/// of the piece lies in one of those cells, its time in the horizon): only the obstacles of
/// the cells its parts' hulls meet are examined. Built from the final check's box tests
/// alone (nothing of the planners' covers), per list of risk levels, asking `stop`.
#[derive(Debug)]
pub struct NearGrid {
    /// Per axis, the cell edges `e_0 ≤ … ≤ e_n` (cell `k` is `[e_k, e_{k+1}]`; neighbours
    /// share the very same float, so the cells leave no gap).
    pub(super) edges: Vec<Vec<f64>>,
    /// Cells per axis (a power of two).
    pub(super) per_axis: usize,
    /// Per cell (row-major, axis 0 slowest), the obstacles not cleared there.
    pub(super) cells: Vec<Vec<u32>>,
    /// Obstacles without a box test, or whose test clears too little to be worth its cells:
    /// examined on every piece.
    pub(super) always: Vec<u32>,
    /// Obstacles in the scene.
    obstacles: usize,
    /// Each obstacle's box-test polynomials at its Δᵢ (`Near::cantelli`): formed by the
    /// build for the obstacles it tests, on first use for the others; the final checks at
    /// these risk levels use them too.
    pub bounds: Vec<OnceLock<NearBound>>,
    /// Per obstacle, what the build's box tests found (`None`: not tested — no box test,
    /// or moving), for the next revision's grid ([`GridsCarried`]).
    tested: Vec<Option<Tested>>,
}

/// What [`NearGrid::build`] found for one obstacle it tested.
#[derive(Clone, Debug)]
enum Tested {
    /// The cells its box test did not clear.
    Cells(Vec<usize>),
    /// It used up [`GRID_MAX_TESTS_PER_OBSTACLE`]: examined on every piece.
    GaveUp,
}

/// Fewest obstacles for which the final check builds its grid ([`NearGrid`]): with fewer,
/// one box test per obstacle and piece costs less than the grid (a few tens of box tests per
/// obstacle, once per scene and risk allocation).
pub const GRID_MIN_OBSTACLES: usize = 64;

/// Most cells of the grid in all (16 384: 128² in the plane, 16³ in space).
pub const GRID_MAX_CELLS: usize = 1 << 14;

/// Cells per axis per `n^(1/dim)` obstacles: about two cells across per obstacle spacing,
/// so that an obstacle's uncleared cells are a few, and a short piece meets a few cells.
pub const GRID_CELLS_PER_SPACING: f64 = 2.0;

/// Most box tests spent on one obstacle's cells: an obstacle that needs more (its region
/// of doubt covers much of the workspace, or the box tests lose their digits at the scene's
/// scale) is examined on every piece instead. A static disk of the benchmark family needs
/// about 50.
pub const GRID_MAX_TESTS_PER_OBSTACLE: usize = 256;

/// After this many obstacles tested, the grid is abandoned (the final check examines every
/// obstacle, as without it) when more than half of them used up their tests: the grid would
/// cost more than it saves (where nearly every obstacle gives up, building the grid takes
/// far longer than its lookups spare).
pub const GRID_ABANDON_AFTER: usize = 16;

/// Most parts of a piece looked up in the grid: a piece is split into about as many parts
/// as the cells it spans along its widest axis (each part's hull then meets few cells).
pub const GRID_MAX_PARTS: usize = 64;

/// Most cells a piece's parts may meet before the grid is not used for it (every obstacle
/// examined instead, as without a grid).
pub const GRID_MAX_CELLS_PER_PIECE: usize = 4096;

impl NearGrid {
    /// Builds the grid for the box tests `near` at risk levels `deltas` (`Ok(None)`: not
    /// worth it, [`GRID_ABANDON_AFTER`]; `Err` when `stop` says stop first). Moving
    /// obstacles get no cells (tested over the whole horizon they sweep the workspace):
    /// they are examined on every piece.
    pub(crate) fn build(
        scene: &Scene,
        near: &[Option<Near>],
        deltas: &[RiskLevel],
        carried: Option<&GridsCarried>,
        stop: &dyn Fn() -> bool,
    ) -> Result<Option<NearGrid>, Interrupted> {
        let mut grid = NearGrid::empty(scene, near.len());
        // the previous revision's grids of the same cells: an unchanged obstacle (the same
        // box test) at the same Δᵢ has the same cells there (the same tests, the same
        // horizon: FramedContours::reusing compared the region)
        let same_cells =
            |g: &NearGrid| g.per_axis == grid.per_axis && g.edges == grid.edges && g.tested.len() == g.obstacles;
        let old_grids: Vec<&(Vec<RiskLevel>, std::sync::Arc<NearGrid>)> =
            carried.map(|c| c.grids.iter().filter(|(_, g)| same_cells(g)).collect()).unwrap_or_default();
        let take_over = |i: usize| -> Option<(Tested, Option<NearBound>)> {
            let j = (*carried?.index.get(i)?)?;
            old_grids.iter().find_map(|(d, g)| {
                (d.get(j)? == deltas.get(i)?).then_some(())?;
                Some((g.tested.get(j)?.clone()?, g.bounds.get(j)?.get().cloned()))
            })
        };
        let horizon = Interval::new(scene.horizon.0, scene.horizon.1);
        let (mut tested, mut gave_up_on) = (0usize, 0usize);
        for (i, (n, d)) in near.iter().zip(deltas).enumerate() {
            if stop() {
                return Err(Interrupted);
            }
            if tested >= GRID_ABANDON_AFTER && 2 * gave_up_on > tested {
                return Ok(None);
            }
            let Some(n) = n.as_ref().filter(|_| !scene.obstacles[i].is_dynamic()) else {
                grid.always.push(i as u32);
                continue;
            };
            tested += 1;
            // an unchanged obstacle's cells from the previous revision's grid, else its own
            let found = match take_over(i) {
                Some((found, bound)) => {
                    if let Some(b) = bound {
                        let _ = grid.bounds[i].set(b);
                    }
                    found
                }
                None => {
                    let g1 = grid.bounds[i].get_or_init(|| n.cantelli(one_minus_enclosed(d)));
                    grid.cells_of(n, g1, horizon)
                }
            };
            match &found {
                Tested::Cells(cells) => cells.iter().for_each(|&c| grid.cells[c].push(i as u32)),
                Tested::GaveUp => {
                    gave_up_on += 1;
                    grid.always.push(i as u32);
                }
            }
            grid.tested[i] = Some(found);
        }
        // a grid that examines most obstacles on every piece anyway saves nothing
        Ok((2 * grid.always.len() <= grid.obstacles).then_some(grid))
    }

    /// A grid with no obstacle filed yet: about [`GRID_CELLS_PER_SPACING`] cells per
    /// obstacle spacing along each axis (a power of two, at most [`GRID_MAX_CELLS`] in
    /// all) over the workspace, for `obstacles` obstacles.
    fn empty(scene: &Scene, obstacles: usize) -> NearGrid {
        let dim = scene.dim;
        let ws = &scene.workspace;
        let spacing_cells = GRID_CELLS_PER_SPACING * (scene.obstacles.len() as f64).powf(1.0 / dim as f64);
        let max_per_axis = (GRID_MAX_CELLS as f64).powf(1.0 / dim as f64).floor() as usize;
        let mut per_axis = 1usize;
        while per_axis < spacing_cells as usize && per_axis * 2 <= max_per_axis.max(1) {
            per_axis *= 2;
        }
        let edges: Vec<Vec<f64>> = (0..dim)
            .map(|d| {
                let (lo, hi) = (ws.lower[d], ws.upper[d]);
                let w = hi - lo;
                // k/n is exact (n a power of two) and the products and sums are monotone in k;
                // the ends are the workspace's own bounds
                (0..=per_axis)
                    .map(|k| match k {
                        0 => lo,
                        k if k == per_axis => hi,
                        k => (lo + w * (k as f64 / per_axis as f64)).min(hi),
                    })
                    .collect()
            })
            .collect();
        let total = per_axis.pow(dim as u32);
        NearGrid {
            edges,
            per_axis,
            cells: vec![Vec::new(); total],
            always: Vec::new(),
            obstacles,
            bounds: (0..obstacles).map(|_| OnceLock::new()).collect(),
            tested: vec![None; obstacles],
        }
    }

    /// The cells a static obstacle's box test (`g1` its Cantelli polynomial at its Δᵢ)
    /// does not clear over the whole horizon, by dyadic subdivision of the cell blocks;
    /// [`Tested::GaveUp`] past [`GRID_MAX_TESTS_PER_OBSTACLE`] tests.
    fn cells_of(&self, n: &Near, g1: &NearBound, horizon: Interval) -> Tested {
        let dim = self.edges.len();
        let mut marked = Vec::new();
        let mut tests = 0usize;
        let mut stack = vec![(vec![0usize; dim], vec![self.per_axis; dim])];
        while let Some((lo, hi)) = stack.pop() {
            tests += 1;
            if tests > GRID_MAX_TESTS_PER_OBSTACLE {
                return Tested::GaveUp;
            }
            let cell_box: Vec<Interval> =
                (0..dim).map(|a| Interval::new(self.edges[a][lo[a]], self.edges[a][hi[a]])).collect();
            if n.clears(&cell_box, horizon, g1) {
                continue;
            }
            // the widest axis of the block, halved; a single cell is marked
            let (axis, width) = (0..dim).map(|a| (a, hi[a] - lo[a])).max_by_key(|&(_, w)| w).unwrap_or((0, 1));
            if width <= 1 {
                marked.push(self.cell_index(&lo));
                continue;
            }
            let mid = lo[axis] + width / 2;
            let (mut lo2, mut hi1) = (lo.clone(), hi.clone());
            lo2[axis] = mid;
            hi1[axis] = mid;
            stack.push((lo2, hi));
            stack.push((lo, hi1));
        }
        Tested::Cells(marked)
    }

    pub(super) fn cell_index(&self, k: &[usize]) -> usize {
        k.iter().fold(0, |acc, &v| acc * self.per_axis + v)
    }

    /// The cells `[k_lo, k_hi]` per axis that cover `hull` (`None` when it leaves the grid).
    fn cell_range(&self, hull: &[Interval]) -> Option<Vec<(usize, usize)>> {
        if hull.len() != self.edges.len() {
            return None;
        }
        hull.iter()
            .zip(&self.edges)
            .map(|(h, e)| {
                let n = e.len() - 1;
                if !(h.lo >= e[0] && h.hi <= e[n]) {
                    return None;
                }
                // the last cell starting at or below lo, the first ending at or above hi
                let lo = e.partition_point(|&x| x <= h.lo).saturating_sub(1).min(n - 1);
                let hi = e.partition_point(|&x| x < h.hi).saturating_sub(1).clamp(lo, n - 1);
                Some((lo, hi))
            })
            .collect()
    }

    /// Each side of a hull clamped to the grid (the workspace): sound for a piece inside
    /// the workspace, and only such a piece is ever judged by its candidates (the caller's
    /// exact workspace check rejects any other first). The outward rounding of a hull
    /// touching a wall would otherwise leave the grid by an ulp.
    fn hull_in_grid(&self, pr: PieceRef<'_>) -> Option<Vec<Interval>> {
        let hull = interval_hull(pr)?;
        if hull.len() != self.edges.len() {
            return None;
        }
        hull.iter()
            .zip(&self.edges)
            .map(|(h, e)| {
                let (a, b) = (e[0], e[e.len() - 1]);
                // a NaN side stays NaN (and leaves the grid); a side wholly outside, too
                (h.lo <= b && h.hi >= a).then(|| Interval { lo: h.lo.max(a), hi: h.hi.min(b) })
            })
            .collect()
    }

    /// The obstacles a piece inside the workspace must be examined against (sorted, without
    /// repeats), or `None` when the grid does not help (a hull that is not available, or too
    /// many cells): then every obstacle.
    pub fn candidates(&self, pr: PieceRef<'_>) -> Option<Vec<usize>> {
        let whole = self.hull_in_grid(pr)?;
        let range = self.cell_range(&whole)?;
        let span = range.iter().map(|(a, b)| b - a + 1).max().unwrap_or(1);
        let parts =
            if span <= 1 { vec![pr] } else { crate::checker::cover_index::piece_parts(pr, span.min(GRID_MAX_PARTS))? };
        let mut seen = vec![false; self.obstacles];
        let mut out: Vec<usize> = self.always.iter().map(|&i| i as usize).collect();
        for &i in &out {
            seen[i] = true;
        }
        let mut cells_met = 0usize;
        for p in parts {
            let r = if span <= 1 { range.clone() } else { self.cell_range(&self.hull_in_grid(p)?)? };
            let count: usize = r.iter().map(|(a, b)| b - a + 1).product();
            cells_met += count;
            if cells_met > GRID_MAX_CELLS_PER_PIECE {
                return None;
            }
            let mut k: Vec<usize> = r.iter().map(|(a, _)| *a).collect();
            'cells: loop {
                for &o in &self.cells[self.cell_index(&k)] {
                    if !seen[o as usize] {
                        seen[o as usize] = true;
                        out.push(o as usize);
                    }
                }
                // the next cell of the block (odometer, last axis fastest)
                for a in (0..k.len()).rev() {
                    if k[a] < r[a].1 {
                        k[a] += 1;
                        continue 'cells;
                    }
                    k[a] = r[a].0;
                }
                break;
            }
        }
        out.sort_unstable();
        Some(out)
    }
}
