//! Joint, exclusive assignment of candidates to markers: motion costs under the filter's
//! covariance with manoeuvres, anchors decided first, neighbours' displacements.

use super::*;

/// Negative log-likelihood of an innovation of squared length `r2` under the motion model's
/// mixture (no manoeuvre: variance `normal`; a manoeuvre, with prior [`MANOEUVRE_PRIOR`]:
/// variance `wide`), relative to a zero innovation: 0 at the prediction, growing slowly over
/// the normal gate and then with the wide one.
pub(super) fn motion_cost(r2: f64, normal: f64, wide: f64) -> f64 {
    let (normal, wide) = (normal.max(1e-9), wide.max(normal).max(1e-9));
    let a0 = (1.0 - MANOEUVRE_PRIOR).ln() - normal.ln();
    let b0 = MANOEUVRE_PRIOR.ln() - wide.ln();
    log_sum_exp(a0, b0) - log_sum_exp(a0 - 0.5 * r2 / normal, b0 - 0.5 * r2 / wide)
}

pub(super) fn log_sum_exp(a: f64, b: f64) -> f64 {
    let m = a.max(b);
    m + ((a - m).exp() + (b - m).exp()).ln()
}

/// Variance the gate opens by (pixels²) for a marker with window `side` after `misses`
/// frames without a measurement: [`TrackerConfig::search_radius_windows`] windows at the
/// gate's edge on the first, growing linearly while coasting and quadratically once lost,
/// never past twice the frame.
pub(super) fn manoeuvre_var(
    config: &TrackerConfig,
    side: f64,
    misses: usize,
    frame_side: f64,
) -> f64 {
    let sigma = config.search_radius_windows * side / GATE_CHI2.sqrt();
    let k = misses as f64 + 1.0;
    let growth = if misses > config.max_coast_frames {
        k * k
    } else {
        k
    };
    (sigma * sigma * growth).min((2.0 * frame_side).powi(2))
}

/// Assign places (columns) to markers (rows) when several markers may be fooled at once (a
/// row of look-alike targets that all jump): the marker whose best place beats its
/// alternatives (another place, or none) by [`ANCHOR_MARGIN`] or more is decided first; it
/// becomes an anchor whose displacement this frame tells the still ambiguous markers near it
/// where to look (nearby markers move alike: one branch, one rig), and the next clearest
/// marker is decided, until none is clear; the rest are assigned jointly
/// ([`assign`]). `cost` is row-major `rows x columns` (infinite: not a candidate); `lasts`
/// each row's marker, its last centre and window side; `anchors` the markers decided before;
/// `coherent(a, b)` whether markers `a` and `b` have moved alike.
///
/// The neighbours' prior chooses between a marker's places: it is taken relative to the
/// free place it favours, so that a marker whose only place lies where its neighbours do not
/// point (at a release, markers pulled alike ring at their own frequencies) still takes it
/// when its own cost allows.
pub(super) fn assign_anchored(
    cost: &[f64],
    columns: usize,
    lasts: &[(usize, Point2<f64>, f64)],
    places: &[Point2<f64>],
    mut anchors: Vec<Anchor>,
    coherent: &dyn Fn(usize, usize) -> bool,
) -> Vec<Option<usize>> {
    let rows = lasts.len();
    let mut result: Vec<Option<usize>> = vec![None; rows];
    let mut fixed = vec![false; rows];
    let mut taken = vec![false; columns];
    let mut adjusted = cost.to_vec();
    // Each round decides one row: at most `rows` rounds.
    for _ in 0..rows {
        let mut clearest: Option<(usize, usize, f64)> = None;
        for r in (0..rows).filter(|&r| !fixed[r]) {
            let row = &cost[r * columns..(r + 1) * columns];
            let (best, margin) = best_and_margin(row, &taken);
            let (marker, last, side) = lasts[r];
            // Markers clear on their own need no neighbours; ambiguous ones take the
            // displacement of the neighbours they have moved alike with as a prior.
            let neighbour = (margin < ANCHOR_MARGIN)
                .then(|| {
                    neighbour_displacement(
                        anchors.iter().filter(|a| coherent(marker, a.marker)),
                        last,
                        side,
                    )
                })
                .flatten();
            let out = &mut adjusted[r * columns..(r + 1) * columns];
            out.copy_from_slice(row);
            if let Some((d, sigma)) = neighbour {
                let expected = last + d;
                let prior = |p: &Point2<f64>| {
                    let z2: f64 = (p - expected).norm_squared() / (sigma * sigma);
                    (0.5 * z2).min(NEIGHBOUR_CAP)
                };
                let least = out
                    .iter()
                    .zip(places)
                    .zip(&taken)
                    .filter(|((o, _), t)| o.is_finite() && !**t)
                    .map(|((_, p), _)| prior(p))
                    .fold(f64::INFINITY, f64::min);
                let least = if least.is_finite() { least } else { 0.0 };
                for (o, p) in out.iter_mut().zip(places) {
                    if o.is_finite() {
                        *o += prior(p) - least;
                    }
                }
            }
            let (best, margin) = if neighbour.is_some() {
                best_and_margin(out, &taken)
            } else {
                (best, margin)
            };
            if let Some(j) = best
                && margin >= ANCHOR_MARGIN
                && clearest.is_none_or(|c| margin > c.2)
            {
                clearest = Some((r, j, margin));
            }
        }
        let Some((r, j, _)) = clearest else { break };
        fixed[r] = true;
        taken[j] = true;
        result[r] = Some(j);
        anchors.push(Anchor {
            marker: lasts[r].0,
            last: lasts[r].1,
            moved: places[j] - lasts[r].1,
        });
    }
    // The rest, jointly, on the costs with their neighbour priors.
    let free: Vec<usize> = (0..rows).filter(|&r| !fixed[r]).collect();
    if !free.is_empty() {
        let mut sub = Vec::with_capacity(free.len() * columns);
        for &r in &free {
            sub.extend(
                adjusted[r * columns..(r + 1) * columns]
                    .iter()
                    .zip(&taken)
                    .map(|(&c, &t)| if t { f64::INFINITY } else { c }),
            );
        }
        let joint = assign(&sub, columns, &vec![UNMATCHED_COST; free.len()]);
        for (&r, j) in free.iter().zip(joint) {
            result[r] = j;
        }
    }
    result
}

/// A marker decided in this frame: its last centre and how far it moved.
pub(super) struct Anchor {
    pub(super) marker: usize,
    pub(super) last: Point2<f64>,
    pub(super) moved: Vector2<f64>,
}

/// A row's cheapest free column (if cheaper than staying unassigned) and by how much it beats
/// the next choice (another free column, or [`UNMATCHED_COST`]).
pub(super) fn best_and_margin(row: &[f64], taken: &[bool]) -> (Option<usize>, f64) {
    let mut best: Option<(usize, f64)> = None;
    let mut second = UNMATCHED_COST;
    for (j, (&c, &t)) in row.iter().zip(taken).enumerate() {
        if t || !c.is_finite() {
            continue;
        }
        match best {
            Some((_, b)) if c >= b => second = second.min(c),
            _ => {
                if let Some((_, b)) = best {
                    second = second.min(b);
                }
                best = Some((j, c));
            }
        }
    }
    match best {
        Some((j, b)) if b < UNMATCHED_COST => (Some(j), second - b),
        _ => (None, 0.0),
    }
}

/// The displacement this frame of the anchors near `last` (within
/// [`NEIGHBOUR_RADIUS_WINDOWS`] windows), weighted by inverse squared distance, and how far
/// to trust it (pixels): half a window, or more when the anchors disagree.
pub(super) fn neighbour_displacement<'a>(
    anchors: impl Iterator<Item = &'a Anchor>,
    last: Point2<f64>,
    side: f64,
) -> Option<(Vector2<f64>, f64)> {
    let reach = NEIGHBOUR_RADIUS_WINDOWS * side;
    let mut sum = Vector2::zeros();
    let mut weight = 0.0;
    let mut near = Vec::new();
    for a in anchors {
        let r = (a.last - last).norm();
        if r < reach {
            let w = 1.0 / (r * r).max(side * side);
            sum += w * a.moved;
            weight += w;
            near.push((w, a.moved));
        }
    }
    if weight <= 0.0 {
        return None;
    }
    let mean = sum / weight;
    let spread = near
        .iter()
        .map(|(w, d)| w * (d - mean).norm_squared())
        .sum::<f64>()
        / weight;
    Some((mean, (0.5 * side).max(spread.sqrt())))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Marker 1, last at the origin with a window of 20 px, after marker 0 (an anchor 40 px
    /// away, which it has moved alike with) moved 20 px right; `cost` is marker 1's row over
    /// `places`.
    fn assign_beside_an_anchor(cost: &[f64], places: &[Point2<f64>]) -> Option<usize> {
        let anchors = vec![Anchor {
            marker: 0,
            last: Point2::new(40.0, 0.0),
            moved: Vector2::new(20.0, 0.0),
        }];
        let lasts = [(1, Point2::origin(), 20.0)];
        let coherent = |_: usize, _: usize| true;
        assign_anchored(cost, places.len(), &lasts, places, anchors, &coherent)[0]
    }

    #[test]
    fn neighbours_choose_between_places() {
        // Two places about as likely by the marker's own motion: the one its neighbour's
        // displacement points to is taken.
        let places = [Point2::new(20.0, 0.0), Point2::new(80.0, 60.0)];
        assert_eq!(assign_beside_an_anchor(&[8.0, 7.5], &places), Some(0));
    }

    #[test]
    fn a_lone_place_against_the_neighbours_is_still_taken() {
        // The marker's only place lies where its neighbour's displacement does not point (a
        // release: markers that were pulled alike ring at their own frequencies), at a cost
        // under staying unmatched: the neighbours choose between places, they do not turn
        // the only one down.
        let places = [Point2::new(80.0, 60.0)];
        assert_eq!(assign_beside_an_anchor(&[10.0], &places), Some(0));
        // Too costly on its own, it stays unmatched.
        assert_eq!(assign_beside_an_anchor(&[12.5], &places), None);
    }
}
