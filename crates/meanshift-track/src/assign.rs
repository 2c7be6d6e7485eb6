//! Optimal exclusive assignment of rows (markers) to columns (candidates) at least total cost:
//! the Hungarian method in its shortest-augmenting-path form (Kuhn 1955; Munkres 1957; this
//! formulation after Jonker and Volgenant 1987), O(n² m) for n rows and m columns. Forbidden
//! pairs have an infinite cost; a row may also stay unassigned, at its `unassigned` cost,
//! which is how "no candidate fits this marker" is weighed against a poor fit.

/// The assignment minimising the sum of `cost[i][j]` over assigned pairs plus `unassigned[i]`
/// over unassigned rows. `cost` is row-major with `columns` entries per row; infinite or NaN
/// entries are forbidden. Returns, per row, its column or `None`.
pub(crate) fn assign(cost: &[f64], columns: usize, unassigned: &[f64]) -> Vec<Option<usize>> {
    let rows = unassigned.len();
    if rows == 0 || cost.len() != rows * columns {
        return vec![None; rows];
    }
    // Each row gets a private "unassigned" column: a square-enough problem in which every
    // row can always be assigned, so the method never fails.
    let width = columns + rows;
    // Finite stand-in for a forbidden pair: more than any sum of allowed costs.
    let allowed = |c: f64| c.is_finite();
    let mut big = 1.0;
    for &c in cost.iter().chain(unassigned) {
        if allowed(c) {
            big += c.abs();
        }
    }
    let big = big * 2.0;
    let at = |i: usize, j: usize| -> f64 {
        if j < columns {
            let c = cost[i * columns + j];
            if allowed(c) { c } else { big }
        } else if j - columns == i {
            if allowed(unassigned[i]) {
                unassigned[i]
            } else {
                big
            }
        } else {
            big
        }
    };
    // Potentials u (rows, 1-based) and v (columns, 1-based); p[j] = row matched to column j.
    let mut u = vec![0.0; rows + 1];
    let mut v = vec![0.0; width + 1];
    let mut p = vec![0usize; width + 1];
    let mut way = vec![0usize; width + 1];
    let mut minv = vec![0.0; width + 1];
    let mut used = vec![false; width + 1];
    for i in 1..=rows {
        p[0] = i;
        let mut j0 = 0;
        minv.iter_mut().for_each(|m| *m = f64::INFINITY);
        used.iter_mut().for_each(|b| *b = false);
        // At most `width` steps: each marks one more column used.
        for _ in 0..=width {
            used[j0] = true;
            let i0 = p[j0];
            let mut delta = f64::INFINITY;
            let mut j1 = 0;
            for j in 1..=width {
                if used[j] {
                    continue;
                }
                let cur = at(i0 - 1, j - 1) - u[i0] - v[j];
                if cur < minv[j] {
                    minv[j] = cur;
                    way[j] = j0;
                }
                if minv[j] < delta {
                    delta = minv[j];
                    j1 = j;
                }
            }
            if j1 == 0 {
                break;
            }
            for j in 0..=width {
                if used[j] {
                    u[p[j]] += delta;
                    v[j] -= delta;
                } else {
                    minv[j] -= delta;
                }
            }
            j0 = j1;
            if p[j0] == 0 {
                break;
            }
        }
        // Augment along the path back to column 0.
        for _ in 0..=width {
            let j1 = way[j0];
            p[j0] = p[j1];
            j0 = j1;
            if j0 == 0 {
                break;
            }
        }
    }
    let mut out = vec![None; rows];
    for j in 1..=columns {
        let i = p[j];
        if i > 0 && allowed(cost[(i - 1) * columns + (j - 1)]) {
            out[i - 1] = Some(j - 1);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every assignment by brute force, for checking.
    fn brute(cost: &[f64], columns: usize, unassigned: &[f64]) -> f64 {
        fn go(i: usize, used: &mut Vec<bool>, cost: &[f64], m: usize, un: &[f64]) -> f64 {
            if i == un.len() {
                return 0.0;
            }
            let mut best = un[i] + go(i + 1, used, cost, m, un);
            for j in 0..m {
                let c = cost[i * m + j];
                if !used[j] && c.is_finite() {
                    used[j] = true;
                    best = best.min(c + go(i + 1, used, cost, m, un));
                    used[j] = false;
                }
            }
            best
        }
        go(0, &mut vec![false; columns], cost, columns, unassigned)
    }

    fn total(cost: &[f64], columns: usize, unassigned: &[f64], a: &[Option<usize>]) -> f64 {
        a.iter()
            .enumerate()
            .map(|(i, j)| j.map_or(unassigned[i], |j| cost[i * columns + j]))
            .sum()
    }

    #[test]
    fn matches_brute_force_on_small_problems() {
        let mut seed = 7u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) as f64 / f64::from(1u32 << 31)
        };
        for case in 0..300 {
            let rows = 1 + case % 5;
            let columns = case % 6;
            let cost: Vec<f64> = (0..rows * columns)
                .map(|_| {
                    let x = next();
                    if x < 0.2 { f64::INFINITY } else { 10.0 * x }
                })
                .collect();
            let unassigned: Vec<f64> = (0..rows).map(|_| 3.0 + 5.0 * next()).collect();
            let a = assign(&cost, columns, &unassigned);
            let mut seen = vec![false; columns];
            for j in a.iter().flatten() {
                assert!(!seen[*j], "column used twice");
                seen[*j] = true;
            }
            let got = total(&cost, columns, &unassigned, &a);
            let want = brute(&cost, columns, &unassigned);
            assert!((got - want).abs() < 1e-9, "case {case}: {got} vs {want}");
        }
    }

    #[test]
    fn the_nearest_pairs_are_not_always_the_best() {
        // Greedy takes (0, 0) at 1 and leaves row 1 with 10; the optimum is 2 + 2.
        let cost = [1.0, 2.0, 2.0, 10.0];
        assert_eq!(assign(&cost, 2, &[50.0, 50.0]), vec![Some(1), Some(0)]);
        // A row whose only candidate is forbidden stays unassigned.
        let cost = [f64::INFINITY, f64::NAN];
        assert_eq!(assign(&cost, 1, &[1.0, 1.0]), vec![None, None]);
        assert_eq!(assign(&[], 0, &[]), Vec::<Option<usize>>::new());
    }
}
