//! Dense univariate polynomials `Σ c_k τ^k`, the form every certification works on
//! (a constraint restricted to a trajectory piece, docs/design.md §5.1).

use super::ring::Ring;

/// A dense univariate polynomial; `coeffs[k]` multiplies `τ^k`. Trailing zeros are trimmed.
#[derive(Clone, Debug, PartialEq)]
pub struct UPoly<C> {
    coeffs: Vec<C>,
}

impl<C: Ring> UPoly<C> {
    /// From coefficients in increasing powers.
    pub fn new(mut coeffs: Vec<C>) -> Self {
        while coeffs.last().is_some_and(|c| c.is_zero()) {
            coeffs.pop();
        }
        UPoly { coeffs }
    }

    /// The zero polynomial.
    pub fn zero() -> Self {
        UPoly { coeffs: Vec::new() }
    }

    /// A constant.
    pub fn constant(c: C) -> Self {
        Self::new(vec![c])
    }

    /// `a + b τ`.
    pub fn linear(a: C, b: C) -> Self {
        Self::new(vec![a, b])
    }

    /// Coefficients in increasing powers (empty for zero).
    pub fn coeffs(&self) -> &[C] {
        &self.coeffs
    }

    /// Degree (0 for constants and for zero).
    pub fn degree(&self) -> usize {
        self.coeffs.len().saturating_sub(1)
    }

    /// Whether this is the zero polynomial.
    pub fn is_zero(&self) -> bool {
        self.coeffs.is_empty()
    }

    /// Coefficient of `τ^k`.
    pub fn coeff(&self, k: usize) -> C {
        self.coeffs.get(k).cloned().unwrap_or_else(C::zero)
    }

    /// Horner evaluation.
    pub fn eval(&self, x: &C) -> C {
        let mut acc = C::zero();
        for c in self.coeffs.iter().rev() {
            acc = acc.rmul(x).radd(c);
        }
        acc
    }

    /// `self + o`.
    pub fn add(&self, o: &Self) -> Self {
        let n = self.coeffs.len().max(o.coeffs.len());
        Self::new((0..n).map(|k| self.coeff(k).radd(&o.coeff(k))).collect())
    }

    /// `self - o`.
    pub fn sub(&self, o: &Self) -> Self {
        let n = self.coeffs.len().max(o.coeffs.len());
        Self::new((0..n).map(|k| self.coeff(k).rsub(&o.coeff(k))).collect())
    }

    /// `c * self`.
    pub fn scale(&self, c: &C) -> Self {
        Self::new(self.coeffs.iter().map(|a| a.rmul(c)).collect())
    }

    /// `-self`.
    pub fn neg(&self) -> Self {
        Self::new(self.coeffs.iter().map(|a| a.rneg()).collect())
    }

    /// `self * o`.
    pub fn mul(&self, o: &Self) -> Self {
        if self.is_zero() || o.is_zero() {
            return Self::zero();
        }
        let mut out = vec![C::zero(); self.coeffs.len() + o.coeffs.len() - 1];
        for (i, a) in self.coeffs.iter().enumerate() {
            if a.is_zero() {
                continue;
            }
            for (j, b) in o.coeffs.iter().enumerate() {
                out[i + j] = out[i + j].radd(&a.rmul(b));
            }
        }
        Self::new(out)
    }

    /// Derivative.
    pub fn derivative(&self) -> Self {
        let mut out = Vec::with_capacity(self.coeffs.len().saturating_sub(1));
        let mut k = C::zero();
        for (i, c) in self.coeffs.iter().enumerate() {
            if i > 0 {
                out.push(c.rmul(&k));
            }
            k = k.radd(&C::one());
        }
        Self::new(out)
    }

    /// `self(a + b τ)`, by Horner in polynomial arithmetic.
    pub fn compose_affine(&self, a: &C, b: &C) -> Self {
        let lin = Self::linear(a.clone(), b.clone());
        let mut acc = Self::zero();
        for c in self.coeffs.iter().rev() {
            acc = acc.mul(&lin).add(&Self::constant(c.clone()));
        }
        acc
    }

    /// Applies `f` to every coefficient.
    pub fn map<D: Ring>(&self, f: impl Fn(&C) -> D) -> UPoly<D> {
        UPoly::new(self.coeffs.iter().map(f).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_rational::BigRational;

    fn q(n: i64) -> BigRational {
        BigRational::from_integer(n.into())
    }

    #[test]
    fn arithmetic() {
        let p = UPoly::new(vec![q(1), q(2), q(0)]); // 1 + 2τ
        assert_eq!(p.degree(), 1);
        let sq = p.mul(&p); // 1 + 4τ + 4τ²
        assert_eq!(sq.coeffs(), &[q(1), q(4), q(4)]);
        assert_eq!(sq.derivative().coeffs(), &[q(4), q(8)]);
        assert_eq!(sq.eval(&q(2)), q(25));
        // (1 + 2τ) at τ = 3 + 2s: 7 + 4s
        assert_eq!(p.compose_affine(&q(3), &q(2)).coeffs(), &[q(7), q(4)]);
        assert!(p.sub(&p).is_zero());
    }
}
