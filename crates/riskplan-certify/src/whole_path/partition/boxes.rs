//! The pieces' hulls over dyadic parts of their time (`PieceBoxes`): where a partition looks for the parts near an obstacle.

use super::*;

/// Parts of a piece the screen encloses separately: 2^5 = 32 equal parts of its time. A
/// piece whose box meets an obstacle's reach may still pass it at every part (its box is
/// the hull of a long, diagonal or curved piece); measured on 512 disks, six in ten of the
/// obstacles that passed the screen of whole pieces were then proven outside by the
/// partition's root box, at the cost of restricting their pieces — the parts' boxes prove
/// most of them outside at a few interval evaluations each. The parts are the partition's
/// own parts at this depth (piece, depth, index), so the partition starts from those kept.
pub const SCREEN_DEPTH: u32 = 5;

/// Enclosures of a trajectory's pieces, for the partition's screen ([`cells_path_risk_in`]),
/// built once for all obstacles of a scene: per piece and per part of its time
/// (2^`SCREEN_DEPTH` of them), each coordinate (time last) over the part, x_v(t(s)) for
/// s in the part, by Horner in interval arithmetic; and a binary tree of hulls over
/// consecutive pieces, so that an obstacle far from a stretch of the trajectory is
/// dismissed for the whole stretch at one evaluation. In the scene's coordinates: each
/// obstacle's screen moves them into its own frame.
pub struct PieceBoxes {
    /// `parts[piece][k]`: the box of part k, s ∈ [k, k + 1]·2^(−SCREEN_DEPTH).
    pub(super) parts: Vec<Vec<Vec<Interval>>>,
    /// The tree; `nodes[0]` is its root (when there are pieces).
    pub(super) nodes: Vec<HullNode>,
}

/// A node of [`PieceBoxes`]' tree: the hull of the boxes of a run of consecutive pieces.
pub(super) struct HullNode {
    pub(super) hull: Vec<Interval>,
    /// The run's first piece (the only one when the node has no children).
    pub(super) first: usize,
    /// The two halves, or `None` for a single piece.
    pub(super) children: Option<(usize, usize)>,
}

impl PieceBoxes {
    /// The boxes of `pieces` (of dimension `dim`). A piece that is not finite or of another
    /// dimension gets the whole line (the partition refuses it anyway).
    pub fn new(pieces: &[PieceRef<'_>], dim: usize) -> PieceBoxes {
        let n_parts = 1usize << SCREEN_DEPTH;
        let scale = (-(SCREEN_DEPTH as i32) as f64).exp2();
        let parts: Vec<Vec<Vec<Interval>>> = pieces
            .iter()
            .map(|piece| {
                if !piece.is_finite() || piece.coeffs.len() != dim {
                    return vec![vec![Interval::ENTIRE; dim + 1]; n_parts];
                }
                let t0 = Interval::point(piece.t0);
                let h = Interval::point(piece.t1) - t0;
                let subs = substitutions(*piece, dim, t0, h, Interval::point);
                (0..n_parts)
                    .map(|k| {
                        // (k·2⁻³ and (k + 1)·2⁻³ are exact)
                        let s = Interval::new(k as f64 * scale, (k + 1) as f64 * scale);
                        subs.iter().map(|u| u.eval(&s)).collect()
                    })
                    .collect()
            })
            .collect();
        let mut boxes = PieceBoxes { parts, nodes: Vec::new() };
        if !pieces.is_empty() {
            boxes.build(0, pieces.len());
        }
        boxes
    }

    /// Adds the node of pieces `first..end` and its subtree; returns its index.
    fn build(&mut self, first: usize, end: usize) -> usize {
        let at = self.nodes.len();
        self.nodes.push(HullNode { hull: Vec::new(), first, children: None });
        let hull_of =
            |a: &[Interval], b: &[Interval]| -> Vec<Interval> { a.iter().zip(b).map(|(x, y)| x.hull(*y)).collect() };
        if end - first == 1 {
            let parts = &self.parts[first];
            self.nodes[at].hull = parts[1..].iter().fold(parts[0].clone(), |acc, b| hull_of(&acc, b));
        } else {
            let mid = first + (end - first) / 2;
            let (a, b) = (self.build(first, mid), self.build(mid, end));
            self.nodes[at].hull = hull_of(&self.nodes[a].hull, &self.nodes[b].hull);
            self.nodes[at].children = Some((a, b));
        }
        at
    }
}
