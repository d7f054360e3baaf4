//! The grid over a scene's covers: per cell, the obstacles whose covers meet it, and the candidate sets a piece's parts look up.

use super::*;

#[derive(Debug)]
pub(super) struct Grid {
    pub(super) n: Vec<usize>,
    size: Vec<f64>,
    pub(super) cells: Vec<Vec<u32>>,
    pub(super) always: Vec<u32>,
    /// Entries per cell, on average over the grid.
    pub(super) mean_entries: f64,
}

impl Grid {
    pub(super) fn cell_range(&self, lower: &[f64], bbox: &[(f64, f64)]) -> Vec<(usize, usize)> {
        bbox.iter()
            .enumerate()
            .map(|(d, &(lo, hi))| (self.axis_cell(lower, d, lo), self.axis_cell(lower, d, hi)))
            .collect()
    }
    /// The cell of coordinate `v` on axis `d` (clamped to the grid; NaN gives the first).
    pub(super) fn axis_cell(&self, lower: &[f64], d: usize, v: f64) -> usize {
        (((v - lower[d]) / self.size[d]).floor().max(0.0) as usize).min(self.n[d] - 1)
    }
    pub(super) fn for_each_cell(&self, range: &[(usize, usize)], mut f: impl FnMut(usize)) {
        let mut idx: Vec<usize> = range.iter().map(|r| r.0).collect();
        loop {
            let mut flat = 0;
            for d in (0..idx.len()).rev() {
                flat = flat * self.n[d] + idx[d];
            }
            f(flat);
            let mut d = 0;
            loop {
                if d == idx.len() {
                    return;
                }
                if idx[d] < range[d].1 {
                    idx[d] += 1;
                    break;
                }
                idx[d] = range[d].0;
                d += 1;
            }
        }
    }
}

/// A set of a scene's obstacles (a bit each), filled by [`SceneIndex::mark_candidates`].
#[derive(Clone, Debug)]
pub struct CandidateSet {
    pub(super) marked: Vec<u64>,
    /// Scratch: the obstacles tested for the current box.
    pub(super) tested: Vec<u64>,
}

impl CandidateSet {
    pub(super) fn mark(&mut self, i: usize) {
        self.marked[i / 64] |= 1 << (i % 64);
    }

    /// The obstacles marked, in increasing order, into `out` (cleared first).
    pub fn emit(&self, out: &mut Vec<usize>) {
        out.clear();
        for (w, &bits) in self.marked.iter().enumerate() {
            let mut b = bits;
            while b != 0 {
                out.push(w * 64 + b.trailing_zeros() as usize);
                b &= b - 1;
            }
        }
    }
}

pub(super) fn overlaps(a: &[(f64, f64)], b: &[(f64, f64)]) -> bool {
    a.iter().zip(b).all(|(x, y)| x.0 <= y.1 && y.0 <= x.1)
}

pub(super) fn build_grid(scene: &Scene, covers: &[std::sync::OnceLock<ObstacleCovers>]) -> Grid {
    let ws = &scene.workspace;
    let dim = scene.dim;
    let total = (covers.len() * GRID_CELLS_PER_OBSTACLE).clamp(1, GRID_MAX_CELLS);
    let per = ((total as f64).powf(1.0 / dim as f64).floor() as usize).max(1);
    let n = vec![per; dim];
    let size: Vec<f64> = (0..dim).map(|d| (ws.upper[d] - ws.lower[d]) / per as f64).collect();
    let mut grid =
        Grid { n, size, cells: vec![Vec::new(); per.pow(dim as u32)], always: Vec::new(), mean_entries: 0.0 };
    for (i, c) in covers.iter().enumerate() {
        let Some(slabs) = c.get().and_then(|c| c.slabs.as_ref()) else {
            grid.always.push(i as u32);
            continue;
        };
        let boxes: Vec<&Vec<(f64, f64)>> = slabs.iter().filter_map(|s| s.cover.as_ref()).collect();
        if boxes.is_empty() {
            continue;
        }
        let mut hull = boxes[0].clone();
        for b in &boxes[1..] {
            for (h, x) in hull.iter_mut().zip(b.iter()) {
                h.0 = h.0.min(x.0);
                h.1 = h.1.max(x.1);
            }
        }
        let range = grid.cell_range(&ws.lower, &hull);
        let mut touched = Vec::new();
        grid.for_each_cell(&range, |cell| touched.push(cell));
        for cell in touched {
            grid.cells[cell].push(i as u32);
        }
    }
    grid.mean_entries = grid.cells.iter().map(Vec::len).sum::<usize>() as f64 / grid.cells.len() as f64;
    grid
}
