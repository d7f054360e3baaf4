//! One obstacle's E[P] and E[P²] compiled in its centred frame (`CompiledContour`) and restricted to pieces (`FastRestriction`).

use super::*;

/// One obstacle's E\[P\] and E\[P²\], compiled in centred variables
/// `(y_1..y_n, s) = (x − c, t − t_c)`.
#[derive(Clone, Debug)]
pub struct CompiledContour {
    frame: Frame,
    mean: Compiled,
    second: Compiled,
    /// The bounds beyond Cantelli in the same frame, compiled on first use (§5.13).
    bounds: std::sync::OnceLock<std::sync::Arc<CompiledBounds>>,
}

/// The two restricted moment polynomials of one obstacle on one piece.
#[derive(Clone, Copy, Debug)]
pub struct FastRestriction<const N: usize = CAPACITY> {
    /// `e1(τ) = E[P](x(t(τ)), t(τ))`.
    pub mean: FPoly<N>,
    /// `e2(τ) = E[P²](…)`.
    pub second: FPoly<N>,
}

impl<const N: usize> FastRestriction<N> {
    /// `g1 = e1² − (1−Δ)·e2` (Cantelli) and `g2 = −e1` (mean), for `1−Δ` enclosed in
    /// `one_minus_delta`; `None` when `e1²` exceeds the capacity.
    pub fn constraints(&self, one_minus_delta: Interval) -> Option<(FPoly<N>, FPoly<N>)> {
        let sq = self.mean.mul(&self.mean)?;
        Some((sq.sub(&self.second.scale(one_minus_delta)), self.mean.neg()))
    }
}

impl CompiledContour {
    /// Compiles a contour in `frame` (`dim + 1` variables: space, then time).
    pub fn new(contour: &RiskContour, frame: &Frame) -> Self {
        let nv = contour.layout().xt_len();
        debug_assert_eq!(frame.len(), nv);
        CompiledContour {
            frame: frame.clone(),
            mean: Compiled::new(&to_frame(&contour.mean, frame), nv),
            second: Compiled::new(&to_frame(&contour.second, frame), nv),
            bounds: std::sync::OnceLock::new(),
        }
    }

    /// Whether Cantelli's two constraints of eq. (15) are proven at the point `xt`
    /// (space, then time; floats used exactly) by interval evaluation of the compiled
    /// E\[P\] and E\[P²\]: `E[P] < 0` and `E[P]² − (1−Δ)·E[P²] > 0` with `1−Δ` enclosed in
    /// `one_minus_delta`. `false` means not proven here (the caller decides exactly).
    pub fn proves_point(&self, xt: &[f64], one_minus_delta: Interval) -> bool {
        if xt.len() != self.frame.len() || xt.iter().any(|v| !v.is_finite()) {
            return false;
        }
        let z = self.frame.point_coords(xt);
        let m = self.mean.eval_box(&z);
        // (a NaN bound fails both comparisons: not proven)
        if m.hi.is_nan() || m.hi >= 0.0 {
            return false;
        }
        let g1 = m * m - one_minus_delta * self.second.eval_box(&z);
        g1.lo > 0.0
    }

    /// The compiled bounds beyond Cantelli of `contour` (the contour this was compiled
    /// from), built on first use.
    pub fn bounds(&self, contour: &RiskContour) -> &CompiledBounds {
        self.bounds.get_or_init(|| std::sync::Arc::new(CompiledBounds::new(contour, &self.frame)))
    }

    /// Whether [`Self::bounds`] are built (for tests).
    pub fn bounds_built(&self) -> bool {
        self.bounds.get().is_some()
    }

    /// E\[P\] restricted to a piece (`subs`: its coordinates from
    /// [`CompiledContour::substitutions`]), enclosed.
    pub fn mean_on(&self, subs: &[FPoly<CAPACITY>]) -> Option<UPoly<Interval>> {
        restricted(&self.mean, subs)
    }

    /// E\[P²\] restricted to a piece, enclosed.
    pub fn second_on(&self, subs: &[FPoly<CAPACITY>]) -> Option<UPoly<Interval>> {
        restricted(&self.second, subs)
    }

    /// E\[P\] restricted to a piece given by its [`Substitution`], in `f64` with a running
    /// error bound ([`Compiled::compose_e`]), enclosed; `None` outside the model (the
    /// caller uses [`CompiledContour::mean_on`] then).
    pub fn mean_on_f64(&self, sub: &Substitution) -> Option<UPoly<Interval>> {
        enclosed_e(&self.mean, sub)
    }

    /// E\[P²\] likewise.
    pub fn second_on_f64(&self, sub: &Substitution) -> Option<UPoly<Interval>> {
        enclosed_e(&self.second, sub)
    }

    /// The frame of the compiled variables.
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// The compiled coordinates of a piece as polynomials in τ ∈ [0, 1]:
    /// `z_d(τ) = (x_d(t0 + hτ) − c_d)·2^(−e_d)`, `z_t(τ) = (t0 + hτ − t_c)·2^(−e_t)`, in
    /// interval arithmetic. `None` when a piece's degree exceeds the capacity or it has
    /// more than 8 coordinates.
    pub fn substitutions<const N: usize>(&self, piece: PieceRef<'_>) -> Option<[FPoly<N>; 9]> {
        let nv = self.frame.len();
        if nv > 9 || nv == 0 {
            return None;
        }
        let center = &self.frame.center;
        let t0 = Interval::point(piece.t0);
        let h = Interval::point(piece.t1) - t0;
        let lin = FPoly::linear(t0, h);
        let mut subs = [FPoly::zero(); 9];
        for (d, sub) in subs.iter_mut().enumerate().take(nv - 1) {
            let row: &[f64] = piece.coeffs.get(d).map(|r| r.as_slice()).unwrap_or(&[]);
            let mut acc = FPoly::zero();
            for &c in row.iter().rev() {
                acc = acc.mul(&lin)?;
                acc.add_assign(&FPoly::constant(Interval::point(c)));
            }
            acc.add_assign(&FPoly::constant(Interval::point(-center[d])));
            *sub = acc.scale(Interval::point(self.frame.inv_scale(d)));
        }
        subs[nv - 1] =
            FPoly::linear(t0 - Interval::point(center[nv - 1]), h).scale(Interval::point(self.frame.inv_scale(nv - 1)));
        Some(subs)
    }

    /// E\[P\] and E\[P²\] restricted to a piece, enclosed, with capacity `N`; `None`
    /// beyond it.
    pub fn restrict_with<const N: usize>(&self, piece: PieceRef<'_>) -> Option<FastRestriction<N>> {
        let subs = self.substitutions::<N>(piece)?;
        let subs = &subs[..self.frame.len()];
        Some(FastRestriction { mean: self.mean.compose(subs)?, second: self.second.compose(subs)? })
    }

    /// E\[P\] and E\[P²\] restricted to a piece, enclosed; `None` beyond [`CAPACITY`].
    pub fn restrict(&self, piece: PieceRef<'_>) -> Option<FastRestriction> {
        self.restrict_with::<CAPACITY>(piece)
    }

    /// Runs `f(g2, g1)` on outward intervals enclosing the coefficients of the mean
    /// and Cantelli constraints restricted to a piece (`1−Δ` given as its nearest float
    /// and whether that float is exact), computed in `f64` with a running error bound
    /// ([`EPoly`]) in the smallest stack buffer that holds them; `None` beyond
    /// [`CAPACITY`], on overflow, or outside the model's range ([`MODEL_FLOOR`]; a
    /// rounded `1−Δ` must be normal too). `subs` are the piece's compiled coordinates
    /// ([`Substitution::new`] in this contour's frame).
    pub fn with_constraints<R>(
        &self,
        subs: &Substitution,
        one_minus_delta: (f64, bool),
        f: impl FnOnce(&[Interval], &[Interval]) -> R,
    ) -> Option<R> {
        fn run<const N: usize, R>(
            c: &CompiledContour,
            sub: &Substitution,
            omd: (f64, bool),
            f: impl FnOnce(&[Interval], &[Interval]) -> R,
        ) -> Option<R> {
            let nv = c.frame.len();
            if nv != sub.nv || !(omd.1 || omd.0.abs() >= MODEL_FLOOR) {
                return None;
            }
            let subs = sub.epolys::<N>()?;
            let subs = &subs[..nv];
            let e1 = c.mean.compose_e(subs)?;
            let e2 = c.second.compose_e(subs)?;
            let g1 = e1.mul(&e1)?.add_signed(&e2.scale(omd.0, u32::from(!omd.1))?, -1.0);
            let (mut b1, mut b2) = ([ZERO; N], [ZERO; N]);
            let n1 = g1.enclosure(&mut b1)?;
            let n2 = e1.enclosure(&mut b2)?;
            for v in &mut b2[..n2] {
                *v = -*v;
            }
            Some(f(&b2[..n2], &b1[..n1]))
        }
        let need = self.restricted_degree(subs.piece_degree) + 1;
        if need <= 8 {
            run::<8, R>(self, subs, one_minus_delta, f)
        } else if need <= 16 {
            run::<16, R>(self, subs, one_minus_delta, f)
        } else {
            run::<CAPACITY, R>(self, subs, one_minus_delta, f)
        }
    }

    /// The degree in τ of `E[P²]` restricted to a piece of degree `k` in t (an upper
    /// bound: total degree times k).
    pub fn restricted_degree(&self, piece_degree: usize) -> usize {
        self.second.degree().max(2 * self.mean.degree()) * piece_degree.max(1)
    }
}
