//! Packing symmetric matrices: raw upper triangles and Clarabel's scaled svec (§4.1).

/// `√2`, the svec scaling of off-diagonal entries.
pub const SQRT2: f64 = std::f64::consts::SQRT_2;

/// Number of entries of the upper triangle of a side-`n` matrix: `n(n+1)/2`.
pub fn svec_len(n: usize) -> usize {
    n * (n + 1) / 2
}

/// Position of entry `(i, j)` (either order) in column-major upper-triangle order:
/// `j(j+1)/2 + i` for `i ≤ j` — Clarabel's svec layout.
pub fn svec_index(i: usize, j: usize) -> usize {
    let (i, j) = if i <= j { (i, j) } else { (j, i) };
    j * (j + 1) / 2 + i
}

/// Side `n` of a matrix whose upper triangle has `len` entries, if `len` is triangular.
pub fn svec_side(len: usize) -> Option<usize> {
    let mut n = 0usize;
    while svec_len(n) < len {
        n += 1;
    }
    (svec_len(n) == len).then_some(n)
}

/// Raw upper triangle (no scaling) of a square matrix, column-major: the layout of a
/// [`GramBlock`](super::GramBlock)'s variables. Only the upper triangle of `m` is read.
pub fn pack_upper(m: &[Vec<f64>]) -> Vec<f64> {
    let n = m.len();
    let mut v = Vec::with_capacity(svec_len(n));
    for j in 0..n {
        v.extend(m.iter().take(j + 1).map(|row| row.get(j).copied().unwrap_or(f64::NAN)));
    }
    v
}

/// Inverse of [`pack_upper`]: the full symmetric matrix. `None` if `v.len()` is not
/// triangular.
pub fn unpack_upper(v: &[f64]) -> Option<Vec<Vec<f64>>> {
    let n = svec_side(v.len())?;
    let mut m = vec![vec![0.0; n]; n];
    for j in 0..n {
        for i in 0..=j {
            let x = v[svec_index(i, j)];
            m[i][j] = x;
            m[j][i] = x;
        }
    }
    Some(m)
}

/// Clarabel's scaled svec of a symmetric matrix: upper triangle column-major,
/// off-diagonal entries times `√2`, so `⟨svec A, svec B⟩ = tr(AB)`.
pub fn pack_svec(m: &[Vec<f64>]) -> Vec<f64> {
    let mut v = pack_upper(m);
    let n = m.len();
    for j in 0..n {
        for i in 0..j {
            v[svec_index(i, j)] *= SQRT2;
        }
    }
    v
}

/// Inverse of [`pack_svec`] (divides off-diagonal entries by `√2`).
pub fn unpack_svec(v: &[f64]) -> Option<Vec<Vec<f64>>> {
    let n = svec_side(v.len())?;
    let mut raw = v.to_vec();
    for j in 0..n {
        for i in 0..j {
            raw[svec_index(i, j)] /= SQRT2;
        }
    }
    unpack_upper(&raw)
}
