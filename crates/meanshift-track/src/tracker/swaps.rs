//! Undoing identity swaps of two markers of one look.
//!
//! Two markers of one look that cross can be taken for each other where their predictions
//! fail (at the turn of a swing, at a release); from then on each follows the other's
//! marker, and a constant-velocity model with a learnt swing keeps the swap for as long as
//! they swing. What tells them apart afterwards is where each swings: a branch marker swings
//! along its own line, which the tracker remembers ([`MarkerState::signature`]: the swing
//! line, kept only while the marker's recent track agrees with it). When over the last
//! [`SWAP_FRAMES`] frames each of the two tracks lies along the other's line and not along
//! its own, the two markers' states are exchanged, and their observations since they were
//! last together are exchanged too (the swap happened there). Any two markers that met within
//! the last [`MAX_REVISED_FRAMES`] frames are compared, not only those whose first-frame
//! colours match: a marker half hidden on the first frame is measured another colour (on a
//! tuning seed of the crossing condition, one of a pair by 80 RGB levels).
//!
//! Two markers of one look can also swap without meeting: one is lost, and found again on
//! the other's marker while the other's track has gone to its own (a release in blur, a
//! twig). A clean swap of such a pair (each track along the other's line, not its own) is
//! undone too, over the frames it was judged on; where it began is not known.
//!
//! One track can also take the other marker without a swap: where they met, `A`'s track
//! went with `B`'s marker while `B`'s track stayed behind (half hidden, or on a look-alike).
//! When `A`'s recent track runs along `B`'s line, moving, far from its own line, and `B`'s
//! track is elsewhere, the two are exchanged the same way: `B` is where `A`'s track is.
//! "Far from its own line" also holds for a track that moves across its own line and along
//! `B`'s ([`crosswise`]) while `B`'s track follows nothing (a line learnt over a pull and a
//! swing can be wide enough to hold such a track within its spreads).
//!
//! Before any swing line is known (two markers of one look that pass through each other
//! during the pull, speeding up, where a constant-velocity prediction lags most), a swap
//! shows as a bounce: both tracks turn back where the markers overlapped. Each overlap is
//! judged once, [`CROSSING_AFTER`] frames after it: when the two paths before it run on
//! into each other's paths after it with a constant acceleration much better than into
//! their own, the two are exchanged from the frame they parted, and their swings are learnt
//! again from the mended tracks.
//!
//! Two markers at rest closer than a window overlap from the first frame, so no crossing is
//! judged when they first move, and a swap there leaves neither with a signature from
//! before it. A branch marker swings about its rest place (its home): when each track's line
//! runs through the other marker's home and one of them far from its own, the two are
//! exchanged ([`Tracker::homes_swapped`]; only with lines learnt from the tracks' own
//! histories, no exchange in the last [`MAX_REVISED_FRAMES`] frames). Two markers that swing
//! along one line (one above the other on a stem pulled along it) have lines through both
//! homes; there each track's recent mean position, the rest place a damped swing centres
//! on, is compared with the homes ([`CENTRE_NEAR_SHARE`]).
//!
//! A signature is only refined by a line along the same direction that is about as tight
//! and centred on it: a track drifting onto another marker's path fits a wider or shifted
//! line, and letting it replace the signature would make the other path look like its own.

use super::*;
use crate::swing::{ConstantAcceleration, SwingLine};

/// Frames of both tracks a swap is judged on (a third of a 1.5 Hz swing at 30 fps; 8 took
/// two frames longer to undo a swap and lost 2 points on the tuning seeds' combined condition).
const SWAP_FRAMES: usize = 6;
/// Of those, frames each marker must have been found in.
const SWAP_MIN_FOUND: usize = 4;
/// The exchanged identities must explain the tracks this much better (ratio of the summed
/// offsets from the lines, in spreads across them).
const SWAP_RATIO: f64 = 0.4;
/// ... and well in themselves: mean offset per frame from the line, spreads.
const SWAP_MAX_OFFSET: f64 = 1.5;
/// A marker's new swing line replaces its signature when their directions agree this well
/// (|cos| of the angle between their normals; 0.9 is 26°).
const SIGNATURE_AGREE: f64 = 0.9;
/// ... and its spread across has not grown by more than this factor.
const SIGNATURE_MAX_GROWTH: f64 = 1.25;
/// Two markers were together (the swap can have happened) when their centres were within
/// this many windows.
const TOGETHER_WINDOWS: f64 = 1.5;
/// A track taken over by another marker lies at least this far from its own line (mean
/// offset over the last [`SWAP_FRAMES`] frames, spreads): well away from where the lines
/// cross, where a track can be along both.
pub(super) const STOLEN_OWN_OFFSET: f64 = 4.0;
/// ... and moves along the other's line by at least this many windows over those frames (a
/// still look-alike on that line is not the other marker).
const STOLEN_MIN_TRAVEL_WINDOWS: f64 = 0.5;

/// ... or, wherever it lies, moves across its own line and along the other's by at least
/// this ratio (see [`crosswise`]; 2 is 63° off a line).
const STOLEN_CROSS_RATIO: f64 = 2.0;

/// Two markers overlap (a crossing, where one can be taken for the other) when their
/// centres are within this many windows: closer than [`TOGETHER_WINDOWS`], so that markers
/// at rest a window and a half apart are not always together.
const CROSSING_WINDOWS: f64 = 1.0;
/// Frames before an overlap and frames after it over which the two paths are judged.
const CROSSING_BEFORE: usize = 5;
const CROSSING_AFTER: usize = 4;
/// Least frames of each side a path must have been followed in.
const CROSSING_MIN_SIDE: usize = 3;
/// The crossed paths must fit a constant acceleration this much better than the paths as
/// tracked (ratio of the summed squared residuals).
const CROSSING_RATIO: f64 = 0.25;
/// ... and well in themselves: root-mean-square residual, windows.
const CROSSING_MAX_RMS_WINDOWS: f64 = 0.3;

/// Homes at least this many windows apart can be told apart by where their tracks swing
/// about ([`Tracker::homes_swapped`]).
const HOMES_APART_WINDOWS: f64 = 2.0;
/// A track swings about another marker's home when its recent positions' mean lies within
/// this share of the two homes' distance of it (and the other track's about its home): a
/// damped swing over a period or more has its mean at its rest place; a pull pulls both
/// tracks' means the same way, so it cannot move each onto the other's home.
const CENTRE_NEAR_SHARE: f64 = 0.25;

/// How far back the observations are exchanged at most (the swing history's length): a
/// caller that reads each frame's result at once sees at most this many earlier frames of a
/// track change later.
pub const MAX_REVISED_FRAMES: usize = 30;

/// Whether a marker's new swing `line` may replace its `signature`: along the same
/// direction, about as tight, and centred on the old line (a track that drifted onto another
/// marker's path fits a wider or shifted line).
fn refines(signature: &SwingLine, line: &SwingLine) -> bool {
    signature.normal.dot(&line.normal).abs() >= SIGNATURE_AGREE
        && line.sigma_px <= SIGNATURE_MAX_GROWTH * signature.sigma_px
        && signature.offset(line.centre) <= 1.0
}

/// Whether a track's recent steps `p` run across its own swing line `own` and along
/// another's, `other`: summed over the steps, the motion across `own` is at least
/// [`STOLEN_CROSS_RATIO`] times the motion along it, and the motion along `other` at least
/// that many times the motion across it. A marker swings along its line, an ellipse at
/// most a third as wide as it is long; a track that moves across its own line and along
/// another marker's follows that marker, however wide its own line's spread (a line learnt
/// over a pull and a swing can be wide enough to hold such a track within its spreads).
fn crosswise(p: &[Point2<f64>], own: SwingLine, other: SwingLine) -> bool {
    let (mut along_own, mut across_own, mut along_other, mut across_other) = (0.0, 0.0, 0.0, 0.0);
    for w in p.windows(2) {
        let d = w[1] - w[0];
        along_own += d.perp(&own.normal).abs();
        across_own += d.dot(&own.normal).abs();
        along_other += d.perp(&other.normal).abs();
        across_other += d.dot(&other.normal).abs();
    }
    across_own >= STOLEN_CROSS_RATIO * along_own && along_other >= STOLEN_CROSS_RATIO * across_other
}

impl Tracker {
    /// Keep each marker's signature line, then exchange any pair of markers of one look
    /// whose tracks run along each other's lines.
    pub(super) fn repair_swaps(&mut self) {
        if matches!(self.config.model, AppearanceModel::Gray { .. }) {
            // Gray targets in rows swing across each other's places (see the home rule).
            return;
        }
        for m in &mut self.markers {
            if !m.last_status.found() {
                continue;
            }
            if let Some(line) = m.swing.line()
                && m.signature.is_none_or(|s| refines(&s, &line))
            {
                m.signature = Some(line);
            }
        }
        let n = self.markers.len();
        // Where each marker was found lately, once (an exchange revises its pair's).
        let mut recent: Vec<Vec<Point2<f64>>> = (0..n).map(|k| self.recent_found(k)).collect();
        for i in 0..n {
            for j in i + 1..n {
                if let Some(from) = self.crossed(i, j) {
                    self.exchange(i, j, Some(from));
                    // Each swing so far was learnt on a path that turned at the overlap, and so
                    // was any line since: both are learnt again from the mended tracks.
                    for k in [i, j] {
                        self.relearn_swing(k);
                        self.markers[k].signature = None;
                    }
                    recent[i] = self.recent_found(i);
                    recent[j] = self.recent_found(j);
                    continue;
                }
                if self.homes_swapped(i, j, &recent[i], &recent[j]) {
                    // The swap lies further back than the lines tell; at least the frames a
                    // swap by the lines is judged on are exchanged, so that the two lines
                    // learnt next from the mended tracks are not a swap again.
                    let len = self.frames();
                    let from = self
                        .last_met(i, j)
                        .map_or(len, |met| met + 1)
                        .min(len.saturating_sub(SWAP_FRAMES));
                    self.exchange(i, j, Some(from));
                    // Whatever signatures the two learnt were learnt on the swapped tracks
                    // (with a signature from before, the lines would have told the swap).
                    for k in [i, j] {
                        self.markers[k].signature = None;
                    }
                    recent[i] = self.recent_found(i);
                    recent[j] = self.recent_found(j);
                    continue;
                }
                let (Some(si), Some(sj)) = (self.markers[i].signature, self.markers[j].signature)
                else {
                    continue;
                };
                // Two that met can have swapped there (whatever their first-frame colours
                // say: a marker half hidden on the first frame was measured another colour).
                // Two that did not may still have: one lost, then found on the other's
                // marker while the other's track had gone to its own; only a clean swap of
                // same-look markers is undone then, over the frames it was judged on.
                let met = self.last_met(i, j).is_some();
                if !met && !same_look(&self.markers[i], &self.markers[j]) {
                    continue;
                }
                let (pi, pj) = (&recent[i], &recent[j]);
                let swapped = swapped(pi, pj, si, sj);
                // Which track took the other's marker (only two that met).
                let taken_by = if !met || swapped {
                    None
                } else if self.stolen(pi, j, si, sj) {
                    Some(i)
                } else if self.stolen(pj, i, sj, si) {
                    Some(j)
                } else {
                    None
                };
                if swapped || taken_by.is_some() {
                    self.exchange(i, j, None);
                    if let Some(k) = taken_by {
                        // The track that took the other's marker now holds what the other's
                        // track knew, left behind on a stem or a look-alike: where its own
                        // marker is, is unknown.
                        self.markers[k].whereabouts_unknown();
                    }
                    recent[i] = self.recent_found(i);
                    recent[j] = self.recent_found(j);
                }
            }
        }
    }

    /// Whether same-look markers `i` and `j`, both found in this frame, swing along lines
    /// through each other's homes and not through their own: a branch marker swings about
    /// its rest place, so a track whose line runs [`STOLEN_OWN_OFFSET`] spreads or more from
    /// its marker's home, while the other track's line runs through that home and its own
    /// line through the other's, follows the other marker (two markers at rest closer than a
    /// window, whose tracks exchanged where they first moved, before either had a line).
    fn homes_swapped(&self, i: usize, j: usize, pi: &[Point2<f64>], pj: &[Point2<f64>]) -> bool {
        let (a, b) = (&self.markers[i], &self.markers[j]);
        if !same_look(a, b) || !a.last_status.found() || !b.last_status.found() {
            return false;
        }
        // Each line is learnt from its own track only (an exchange moves the swing history
        // with the state, and the frames before it may hold the other marker's path).
        let now = self.frames();
        if [a, b]
            .iter()
            .any(|m| m.exchanged_at.is_some_and(|f| f + MAX_REVISED_FRAMES > now))
        {
            return false;
        }
        let (Some(li), Some(lj)) = (a.swing.line(), b.swing.line()) else {
            return false;
        };
        // The lines are the tracks' own now: a swing exchanged or mended lately can hold
        // another path than the one the track follows.
        if !along(pi, &li) || !along(pj, &lj) {
            return false;
        }
        let (own_i, own_j) = (li.offset(a.home), lj.offset(b.home));
        let (other_i, other_j) = (li.offset(b.home), lj.offset(a.home));
        let lines_swapped = own_i.max(own_j) >= STOLEN_OWN_OFFSET
            && other_i <= SWAP_MAX_OFFSET
            && other_j <= SWAP_MAX_OFFSET
            && other_i + other_j < SWAP_RATIO * (own_i + own_j);
        // Two markers swinging along one line (one above the other on a stem pulled along
        // it) have lines through both homes; where each swings about tells them apart.
        let apart = (a.home - b.home).norm();
        let window = window_px(a).max(window_px(b));
        let centres_swapped = apart >= HOMES_APART_WINDOWS * window
            && (li.centre - b.home).norm() <= CENTRE_NEAR_SHARE * apart
            && (lj.centre - a.home).norm() <= CENTRE_NEAR_SHARE * apart;
        lines_swapped || centres_swapped
    }

    /// Where marker `k` was found in the last [`SWAP_FRAMES`] frames.
    fn recent_found(&self, k: usize) -> Vec<Point2<f64>> {
        let obs = &self.tracks[k].observations;
        obs[obs.len().saturating_sub(SWAP_FRAMES)..]
            .iter()
            .filter(|o| followed(o))
            .filter_map(|o| o.center)
            .collect()
    }

    /// Whether `i`'s recent track has followed `j`'s marker: it runs along `j`'s line, moving,
    /// far from its own line, while `j`'s track is elsewhere (a marker that took the other's
    /// marker where they met, whose partner's track was left behind, half hidden or on a
    /// look-alike, rather than on `i`'s marker: not a swap, but `j`'s marker is where `i`'s
    /// track is).
    fn stolen(&self, pi: &[Point2<f64>], j: usize, si: SwingLine, sj: SwingLine) -> bool {
        let (Some(&first), Some(&last)) = (pi.first(), pi.last()) else {
            return false;
        };
        if pi.len() < SWAP_MIN_FOUND {
            return false;
        }
        let mean =
            |line: &SwingLine| pi.iter().map(|&p| line.offset(p)).sum::<f64>() / pi.len() as f64;
        let window = window_px(&self.markers[j]);
        let apart = self.tracks[j]
            .observations
            .last()
            .and_then(|o| o.center)
            .is_none_or(|c| (c - last).norm() > window);
        // Moving across its own line counts only while the other's track is not
        // following a marker: found on its likeness (at least as alike as that marker
        // usually is) and moving as far as this track must. With both following, two
        // tracks each along a line are a swap or nothing (an elliptic swing seen at its
        // turn moves across its line for a while); a track left behind on a stem or a
        // look-alike, half hidden, stands still or finds nothing.
        let obs = &self.tracks[j].observations;
        let mut other_found = obs[obs.len().saturating_sub(SWAP_FRAMES)..]
            .iter()
            .filter(|o| o.status.found() && self.markers[j].typical(o.confidence))
            .filter_map(|o| o.center);
        let other_following = match (other_found.next(), other_found.next_back()) {
            (Some(a), Some(b)) => (b - a).norm() >= STOLEN_MIN_TRAVEL_WINDOWS * window,
            _ => false,
        };
        mean(&sj) <= SWAP_MAX_OFFSET
            && (mean(&si) >= STOLEN_OWN_OFFSET || (!other_following && crosswise(pi, si, sj)))
            && (last - first).norm() >= STOLEN_MIN_TRAVEL_WINDOWS * window
            && apart
    }

    /// The last frame, at most [`MAX_REVISED_FRAMES`] back, on which markers `i` and `j` were
    /// within [`TOGETHER_WINDOWS`] windows of each other.
    fn last_met(&self, i: usize, j: usize) -> Option<usize> {
        let together =
            TOGETHER_WINDOWS * window_px(&self.markers[i]).max(window_px(&self.markers[j]));
        let (oa, ob) = (&self.tracks[i].observations, &self.tracks[j].observations);
        let len = oa.len().min(ob.len());
        (len.saturating_sub(MAX_REVISED_FRAMES)..len)
            .rev()
            .find(|&f| match (oa[f].center, ob[f].center) {
                (Some(p), Some(q)) => (p - q).norm() < together,
                _ => false,
            })
    }

    /// Whether markers `i` and `j` crossed where their tracks bounced: they overlapped
    /// (within [`CROSSING_WINDOWS`]) until [`CROSSING_AFTER`] frames ago, and each one's path before the overlap runs on smoothly (a constant
    /// acceleration) into the other's path after it, much better than into its own. Two
    /// markers of one look that pass each other while they speed up (a pull) are where a
    /// constant-velocity prediction lags most, and can come out of the overlap exchanged
    /// before any swing line is known. Returns the first frame to exchange from.
    fn crossed(&self, i: usize, j: usize) -> Option<usize> {
        let window = window_px(&self.markers[i]).max(window_px(&self.markers[j]));
        let overlap = CROSSING_WINDOWS * window;
        let (oa, ob) = (&self.tracks[i].observations, &self.tracks[j].observations);
        let len = oa.len().min(ob.len());
        let apart = |f: usize| match (oa[f].center, ob[f].center) {
            (Some(p), Some(q)) => (p - q).norm() >= overlap,
            _ => true,
        };
        // They overlapped last on the frame before the judged ones, which end with this one
        // (each overlap is judged once, so an exchange is never judged again).
        let last = len.checked_sub(CROSSING_AFTER + 1)?;
        if apart(last) || (last + 1..len).any(|f| !apart(f)) {
            return None;
        }
        let first = (0..=last).rev().take_while(|&f| !apart(f)).last()?;
        if first < CROSSING_BEFORE + 1 {
            return None;
        }
        let path =
            |obs: &[Observation], frames: std::ops::Range<usize>| -> Vec<(f64, Point2<f64>)> {
                frames
                    .filter(|&f| followed(&obs[f]))
                    .filter_map(|f| obs[f].center.map(|c| (f as f64 - last as f64, c)))
                    .collect()
            };
        let before = first - CROSSING_BEFORE..first;
        let after = last + 1..len;
        let (bi, bj) = (path(oa, before.clone()), path(ob, before));
        let (ai, aj) = (path(oa, after.clone()), path(ob, after));
        if [&bi, &bj, &ai, &aj]
            .iter()
            .any(|p| p.len() < CROSSING_MIN_SIDE)
        {
            return None;
        }
        let joined = |b: &[(f64, Point2<f64>)], a: &[(f64, Point2<f64>)]| {
            let all: Vec<_> = b.iter().chain(a).copied().collect();
            ConstantAcceleration::fit(&all).map(|f| f.residual)
        };
        let keep = joined(&bi, &ai)? + joined(&bj, &aj)?;
        let cross = joined(&bi, &aj)? + joined(&bj, &ai)?;
        let points = (bi.len() + bj.len() + ai.len() + aj.len()) as f64;
        let rms_limit = CROSSING_MAX_RMS_WINDOWS * window;
        (cross < CROSSING_RATIO * keep && cross / points <= rms_limit * rms_limit)
            .then_some(last + 1)
    }

    /// Learn marker `k`'s swing again from its track's followed frames.
    fn relearn_swing(&mut self, k: usize) {
        let obs = &self.tracks[k].observations;
        let swing = &mut self.markers[k].swing;
        swing.clear();
        let start = obs.len().saturating_sub(MAX_REVISED_FRAMES + 1);
        for (f, o) in obs
            .iter()
            .enumerate()
            .skip(start)
            .filter(|(_, o)| followed(o))
        {
            if let Some(c) = o.center {
                swing.record(f as u64, c);
            }
        }
    }

    /// Exchange what `i` and `j` know of where they are (motion, swing, surroundings, an
    /// adaptive window's size), keep what they are (name, look, home, signature, a fixed
    /// window), and exchange their observations from
    /// `from` (by default, since they were last together).
    fn exchange(&mut self, i: usize, j: usize, from: Option<usize>) {
        let (a, b) = self.markers.split_at_mut(j);
        let (a, b) = (&mut a[i], &mut b[0]);
        std::mem::swap(&mut a.filter, &mut b.filter);
        std::mem::swap(&mut a.swing, &mut b.swing);
        std::mem::swap(&mut a.acceleration_px, &mut b.acceleration_px);
        std::mem::swap(&mut a.last_center, &mut b.last_center);
        if self.config.window == WindowMode::Adaptive {
            // The window measured on the marker each filter followed; a fixed window is
            // the marker's own.
            std::mem::swap(&mut a.size, &mut b.size);
        }
        std::mem::swap(&mut a.depth_m, &mut b.depth_m);
        std::mem::swap(&mut a.misses, &mut b.misses);
        std::mem::swap(&mut a.weak_run, &mut b.weak_run);
        std::mem::swap(&mut a.weak_place, &mut b.weak_place);
        std::mem::swap(&mut a.last_status, &mut b.last_status);
        std::mem::swap(&mut a.context, &mut b.context);
        std::mem::swap(&mut a.context_level, &mut b.context_level);
        std::mem::swap(&mut a.context_var, &mut b.context_var);
        std::mem::swap(&mut a.gate_var, &mut b.gate_var);
        let now = self.tracks[i].observations.len();
        a.exchanged_at = Some(now);
        b.exchanged_at = Some(now);
        // From the frame after they were last together (the swap happened there), or over
        // the frames the swap was judged on.
        let len = self.tracks[i]
            .observations
            .len()
            .min(self.tracks[j].observations.len());
        let from = from.unwrap_or_else(|| {
            self.last_met(i, j)
                .map_or(len.saturating_sub(SWAP_FRAMES), |met| met + 1)
        });
        let (ta, tb) = self.tracks.split_at_mut(j);
        let (oa, ob) = (&mut ta[i].observations, &mut tb[0].observations);
        for f in from..len {
            std::mem::swap(&mut oa[f], &mut ob[f]);
        }
    }
}

/// Whether the recent track `p` (at least [`SWAP_MIN_FOUND`] places) lies along `line`: a
/// mean offset of at most [`SWAP_MAX_OFFSET`] spreads.
fn along(p: &[Point2<f64>], line: &SwingLine) -> bool {
    p.len() >= SWAP_MIN_FOUND
        && p.iter().map(|&q| line.offset(q)).sum::<f64>() / p.len() as f64 <= SWAP_MAX_OFFSET
}

/// Whether the recent tracks `pi` and `pj` of two markers lie along each other's lines `sj`
/// and `si`, not their own.
fn swapped(pi: &[Point2<f64>], pj: &[Point2<f64>], si: SwingLine, sj: SwingLine) -> bool {
    if pi.len() < SWAP_MIN_FOUND || pj.len() < SWAP_MIN_FOUND {
        return false;
    }
    let mean = |pts: &[Point2<f64>], line: &SwingLine| {
        pts.iter().map(|&p| line.offset(p)).sum::<f64>() / pts.len() as f64
    };
    let keep = mean(pi, &si) + mean(pj, &sj);
    let (swap_i, swap_j) = (mean(pi, &sj), mean(pj, &si));
    swap_i <= SWAP_MAX_OFFSET && swap_j <= SWAP_MAX_OFFSET && swap_i + swap_j < SWAP_RATIO * keep
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::swing::SwingLine;
    use crate::tracker::two_red_markers;

    /// Two markers of one colour, with the lines they are known by.
    fn tracker() -> Result<Tracker> {
        let mut t = two_red_markers()?;
        // A swings horizontally about (60, 30), B vertically about (100, 30).
        t.markers[0].signature = Some(SwingLine {
            centre: Point2::new(60.0, 30.0),
            normal: Vector2::new(0.0, 1.0),
            sigma_px: 3.0,
            half_length_px: 15.0,
        });
        t.markers[1].signature = Some(SwingLine {
            centre: Point2::new(100.0, 30.0),
            normal: Vector2::new(1.0, 0.0),
            sigma_px: 3.0,
            half_length_px: 15.0,
        });
        Ok(t)
    }

    fn push(t: &mut Tracker, a: Point2<f64>, b: Point2<f64>) {
        for (k, p) in [(0, a), (1, b)] {
            t.tracks[k].observations.push(Observation {
                center: Some(p),
                window: PixelRect::centered_at(p, 11, 11),
                status: TrackStatus::Tracked,
                confidence: 1.0,
            });
        }
    }

    /// [`push`], and A's and B's swings record it as frame `k + 1`.
    fn push_swinging(t: &mut Tracker, k: u32, a: Point2<f64>, b: Point2<f64>) {
        push(t, a, b);
        let frame = u64::from(k) + 1;
        t.markers[0].swing.record(frame, a);
        t.markers[1].swing.record(frame, b);
    }

    /// `t` after [`Tracker::repair_swaps`], with A's centres before it.
    fn repaired(mut t: Tracker) -> (Tracker, Vec<Option<Point2<f64>>>) {
        let before = t.tracks[0].observations.iter().map(|o| o.center).collect();
        t.repair_swaps();
        (t, before)
    }

    /// Frames 1-3 together; then 8 frames with A on B's line and B on A's (`swapped`) or
    /// each on its own.
    fn run(swapped: bool) -> Result<(Tracker, Vec<Option<Point2<f64>>>)> {
        let mut t = tracker()?;
        for _ in 0..3 {
            push(&mut t, Point2::new(78.0, 30.0), Point2::new(84.0, 30.0));
        }
        for k in 0..8 {
            let horizontal = Point2::new(50.0 + 3.0 * f64::from(k), 30.5);
            let vertical = Point2::new(100.5, 18.0 + 3.0 * f64::from(k));
            if swapped {
                push(&mut t, vertical, horizontal);
            } else {
                push(&mut t, horizontal, vertical);
            }
        }
        t.markers[0].filter.position = Point2::new(100.0, 40.0);
        t.markers[1].filter.position = Point2::new(71.0, 30.0);
        Ok(repaired(t))
    }

    #[test]
    fn tracks_along_each_others_lines_are_exchanged_back_to_where_they_met() -> Result<()> {
        let (t, before) = run(true)?;
        let a = &t.tracks[0].observations;
        // Frames 0-3 (first frame, then together) stay; the 8 after are exchanged.
        for (f, o) in a.iter().enumerate() {
            if f <= 3 {
                assert_eq!(o.center, before[f], "frame {f}");
            } else {
                let c = o.center.expect("found");
                assert!((c.y - 30.5).abs() < 1e-9, "frame {f}: {c}");
            }
        }
        assert!(
            t.tracks[1].observations[4..]
                .iter()
                .all(|o| { o.center.is_some_and(|c| (c.x - 100.5).abs() < 1e-9) })
        );
        // Where each is now goes with the exchange; who each is stays; both states followed
        // a marker, so neither is looked for as missing.
        assert_eq!(t.markers[0].filter.position, Point2::new(71.0, 30.0));
        assert!(t.markers.iter().all(|m| m.misses == 0));
        assert_eq!(t.markers[0].id, "A");
        assert_eq!(
            t.markers[0].signature.map(|s| s.centre),
            Some(Point2::new(60.0, 30.0))
        );
        Ok(())
    }

    /// A and B (homes (20, 30) and (150, 30)) after 16 frames with no signature known: A's
    /// track swinging up and down through B's home and B's track along a line through A's
    /// home (`swapped`), or each through its own; with `exchanged_at`, A's state was
    /// exchanged with another's on that frame.
    fn run_homes(swapped: bool, exchanged_at: Option<usize>) -> Result<Tracker> {
        let mut t = two_red_markers()?;
        for k in 0..16_u32 {
            let s = f64::from(k % 8) - 3.5;
            let vertical = Point2::new(150.0 + 0.3 * s.signum(), 30.0 + 4.0 * s);
            let horizontal = Point2::new(20.0 + 5.0 * s, 30.0 - 0.3 * s.signum());
            let (a, b) = if swapped {
                (vertical, horizontal)
            } else {
                (horizontal, vertical)
            };
            push_swinging(&mut t, k, a, b);
        }
        for m in &mut t.markers {
            m.last_status = TrackStatus::Tracked;
        }
        t.markers[0].exchanged_at = exchanged_at;
        t.repair_swaps();
        Ok(t)
    }

    #[test]
    fn tracks_swinging_through_each_others_homes_are_exchanged() -> Result<()> {
        let t = run_homes(true, None)?;
        // Exchanged: A's track now swings through A's home, and at least the frames a
        // swap by the lines is judged on are A's marker's.
        let line = t.markers[0].swing.line().expect("a line");
        assert!(line.offset(t.markers[0].home) < 1.0);
        let obs = &t.tracks[0].observations;
        assert!(
            obs[obs.len() - SWAP_FRAMES..]
                .iter()
                .all(|o| o.center.is_some_and(|c| c.x < 60.0))
        );
        assert!(t.markers.iter().all(|m| m.signature.is_none()));
        assert_eq!(t.markers[0].id, "A");
        // Each through its own home: left alone.
        let t = run_homes(false, None)?;
        let a_own = |t: &Tracker| {
            t.tracks[0].observations[1..]
                .iter()
                .all(|o| o.center.is_some_and(|c| c.x < 60.0))
        };
        assert!(a_own(&t));
        // Swapped, but A's swing history holds frames from before an exchange 10 frames
        // ago (under `MAX_REVISED_FRAMES`): not judged by it, left alone.
        let t = run_homes(true, Some(7))?;
        assert!(
            t.tracks[0].observations[1..]
                .iter()
                .all(|o| o.center.is_some_and(|c| c.x > 100.0))
        );
        Ok(())
    }

    /// A and B with homes 60 px apart on one horizontal line, after 24 frames of tracks
    /// swinging 40 px each way along it (so that each line runs through both homes) about
    /// `centre_a` and `centre_b`.
    fn run_one_line(centre_a: f64, centre_b: f64) -> Result<Tracker> {
        let mut t = two_red_markers()?;
        t.markers[0].home = Point2::new(60.0, 30.0);
        t.markers[1].home = Point2::new(120.0, 30.0);
        for k in 0..24_u32 {
            let s = 40.0 * (f64::from(k) * std::f64::consts::TAU / 12.0).cos();
            let wobble = 0.3 * f64::from(k % 2);
            let (a, b) = (
                Point2::new(centre_a + s, 30.0 + wobble),
                Point2::new(centre_b - s, 30.0 - wobble),
            );
            push_swinging(&mut t, k, a, b);
        }
        for m in &mut t.markers {
            m.last_status = TrackStatus::Tracked;
        }
        t.repair_swaps();
        Ok(t)
    }

    #[test]
    fn two_on_one_line_are_told_by_where_they_swing_about() -> Result<()> {
        // Each line runs through both homes: the lines alone tell nothing.
        let t = run_one_line(120.0, 60.0)?;
        let (la, lb) = (
            t.markers[0].swing.line().expect("a line"),
            t.markers[1].swing.line().expect("a line"),
        );
        assert!(la.offset(t.markers[0].home) < 1.0 && lb.offset(t.markers[1].home) < 1.0);
        // A's track swung about B's home and B's about A's: exchanged, A's swing about A's
        // home, and its frames since the two last met are A's marker's.
        let centre = |t: &Tracker| t.markers[0].swing.line().expect("a line").centre.x;
        assert!((centre(&t) - 60.0).abs() < 5.0, "{}", centre(&t));
        assert_eq!(t.markers[0].id, "A");
        let (a, b) = (&t.tracks[0].observations, &t.tracks[1].observations);
        let met = (1..a.len())
            .rev()
            .find(|&f| match (a[f].center, b[f].center) {
                (Some(p), Some(q)) => (p - q).norm() <= TOGETHER_WINDOWS * 11.0,
                _ => false,
            });
        let from = (met.expect("met") + 1).min(a.len() - SWAP_FRAMES);
        for (f, o) in a.iter().enumerate().skip(1) {
            let s = 40.0 * ((f - 1) as f64 * std::f64::consts::TAU / 12.0).cos();
            let x = if f >= from { 60.0 - s } else { 120.0 + s };
            assert!(
                o.center.is_some_and(|c| (c.x - x).abs() < 1e-9),
                "frame {f}"
            );
        }
        // Each about its own home: left alone.
        let t = run_one_line(60.0, 120.0)?;
        assert!((centre(&t) - 60.0).abs() < 5.0, "{}", centre(&t));
        // Both pulled 60 px the same way (A's on B's home, B's beyond it): not a swap.
        let t = run_one_line(120.0, 180.0)?;
        assert!((centre(&t) - 120.0).abs() < 5.0, "{}", centre(&t));
        Ok(())
    }

    /// Frames 1-3 together; then 8 frames with A moving down B's line below the lines'
    /// crossing (`moving`) or still there, while B's track stays behind on its own line.
    fn run_taken(moving: bool) -> Result<(Tracker, Vec<Option<Point2<f64>>>)> {
        let mut t = tracker()?;
        for _ in 0..3 {
            push(&mut t, Point2::new(78.0, 30.0), Point2::new(84.0, 30.0));
        }
        for k in 0..8 {
            let step = if moving { 3.0 * f64::from(k) } else { 0.0 };
            push(
                &mut t,
                Point2::new(100.5, 40.0 + step),
                Point2::new(100.0, 8.0),
            );
        }
        // A's filter follows what it took (B's marker, moving down); B's stands on a stem,
        // with a velocity left from before.
        t.markers[0].filter.velocity = Vector2::new(0.0, 3.0);
        t.markers[1].filter.velocity = Vector2::new(5.0, 0.0);
        for m in &mut t.markers {
            m.last_status = TrackStatus::Tracked;
        }
        Ok(repaired(t))
    }

    #[test]
    fn a_track_that_took_the_other_marker_is_given_to_it() -> Result<()> {
        let (t, before) = run_taken(true)?;
        let b = &t.tracks[1].observations;
        // B now has what A's track followed, from the frame after they met.
        for (f, o) in b.iter().enumerate().skip(4) {
            assert_eq!(o.center, before[f], "frame {f}");
        }
        assert!(
            t.tracks[0].observations[4..]
                .iter()
                .all(|o| o.center == Some(Point2::new(100.0, 8.0)))
        );
        // B goes on with the motion A's track followed; A, given what B's track stood on,
        // is looked for as a marker missing, with no velocity (where it is found next is
        // not a jump made in one frame).
        assert_eq!(t.markers[1].filter.velocity, Vector2::new(0.0, 3.0));
        assert_eq!(t.markers[1].misses, 0);
        assert_eq!(t.markers[0].filter.velocity, Vector2::zeros());
        assert!(t.markers[0].misses >= STOP_AFTER_MISSES);
        assert_eq!(t.markers[0].last_status, TrackStatus::Predicted);
        // Without motion along B's line (a still look-alike there), nothing changes.
        let (t, before) = run_taken(false)?;
        let after: Vec<_> = t.tracks[0].observations.iter().map(|o| o.center).collect();
        assert_eq!(after, before);
        Ok(())
    }

    /// As [`run_taken`], with A known by a wide line that reaches over B's (a line learnt
    /// over a pull and a swing), and A's track moving down B's line by 3 px a frame while
    /// drifting `drift_px` a frame along its own; B's track coasting on a weak measurement
    /// (half hidden), or found (`b_found`) standing still or running up its own line
    /// (`b_moving`).
    fn run_taken_within_own_spread(
        drift_px: f64,
        b_found: bool,
        b_moving: bool,
    ) -> Result<(Tracker, Vec<Option<Point2<f64>>>)> {
        let mut t = tracker()?;
        t.markers[0].signature = Some(SwingLine {
            centre: Point2::new(80.0, 30.0),
            normal: Vector2::new(0.0, 1.0),
            sigma_px: 8.0,
            half_length_px: 30.0,
        });
        for _ in 0..3 {
            push(&mut t, Point2::new(78.0, 30.0), Point2::new(84.0, 30.0));
        }
        for k in 0..8 {
            let k = f64::from(k);
            // B's track stands still (left behind) or runs up its own line by 2 px a frame.
            let b_y = if b_moving { -2.0 * k } else { 0.0 };
            push(
                &mut t,
                Point2::new(96.0 + drift_px * k, 20.0 + 3.0 * k),
                Point2::new(100.0, b_y),
            );
        }
        if !b_found {
            for o in t.tracks[1].observations.iter_mut().skip(4) {
                o.status = TrackStatus::Predicted;
                o.confidence = 0.4;
            }
        }
        Ok(repaired(t))
    }

    #[test]
    fn a_track_moving_across_its_own_line_and_along_the_others_is_given_to_it() -> Result<()> {
        // Every place of A's track lies within two spreads of A's wide line, but it moves
        // straight across that line, along B's, while B's track finds nothing: B's marker.
        let (t, before) = run_taken_within_own_spread(0.0, false, false)?;
        let b = &t.tracks[1].observations;
        for (f, o) in b.iter().enumerate().skip(4) {
            assert_eq!(o.center, before[f], "frame {f}");
        }
        // Moving 30° off B's line (as far along A's own line as 1.7 across it): A's own
        // swing seen at a slant, not taken for B's.
        let (t, before) =
            run_taken_within_own_spread(3.0 * 30_f64.to_radians().tan(), false, false)?;
        let after: Vec<_> = t.tracks[0].observations.iter().map(|o| o.center).collect();
        assert_eq!(after, before);
        // B's track found, but standing still (on a stem, its marker half hidden): the same.
        let (t, before) = run_taken_within_own_spread(0.0, true, false)?;
        let b = &t.tracks[1].observations;
        for (f, o) in b.iter().enumerate().skip(4) {
            assert_eq!(o.center, before[f], "frame {f}");
        }
        // B's track following a marker along its line: A at the turn of an elliptic swing,
        // left alone.
        let (t, before) = run_taken_within_own_spread(0.0, true, true)?;
        let after: Vec<_> = t.tracks[0].observations.iter().map(|o| o.center).collect();
        assert_eq!(after, before);
        Ok(())
    }

    #[test]
    fn a_clean_swap_of_two_that_never_met_is_undone_over_the_judged_frames() -> Result<()> {
        let mut t = tracker()?;
        // Never within a window and a half: A goes down B's line while B's track runs
        // along A's, 30 px apart or more.
        for k in 0..8 {
            push(
                &mut t,
                Point2::new(100.5, 18.0 + 3.0 * f64::from(k)),
                Point2::new(50.0 + 3.0 * f64::from(k), 30.5),
            );
        }
        assert!(t.last_met(0, 1).is_none());
        let before: Vec<_> = t.tracks[0].observations.iter().map(|o| o.center).collect();
        let b_before: Vec<_> = t.tracks[1].observations.iter().map(|o| o.center).collect();
        t.repair_swaps();
        let len = before.len();
        let b: Vec<_> = t.tracks[1].observations.iter().map(|o| o.center).collect();
        // The judged frames are exchanged; the earlier ones, where nothing says they were
        // swapped, are not.
        assert_eq!(b[len - SWAP_FRAMES..], before[len - SWAP_FRAMES..]);
        assert_eq!(b[..len - SWAP_FRAMES], b_before[..len - SWAP_FRAMES]);
        Ok(())
    }

    /// Two markers of one colour on one row, 40 px apart, pulled towards each other with a
    /// constant acceleration (`pass`: through each other) or each decelerating to a turn
    /// beside the other and going back; the tracks bounce where the markers overlap (3
    /// frames), then run on for `CROSSING_AFTER` frames.
    fn overlap(pass: bool) -> Result<(Tracker, Vec<Option<Point2<f64>>>)> {
        let mut t = two_red_markers()?;
        // Path of A (B mirrors it about x = 96): t from -8 to the end.
        let a_at = |k: f64| -> f64 {
            if pass {
                76.0 + 0.25 * (k + 8.0).powi(2)
            } else {
                // Decelerates to its turn at 91 (10 px from B's) in the middle of the
                // overlap, then goes back.
                91.0 - 0.4 * (k - 1.0).powi(2)
            }
        };
        let total = 8 + 3 + CROSSING_AFTER;
        for f in 0..total {
            let k = f as f64 - 8.0;
            let (a, b) = (a_at(k), 192.0 - a_at(k));
            // Where they overlap, each track keeps to its own side of the other; after it,
            // each track is on the side it came from (a bounce, whatever the markers did).
            let (ta, tb) = if f >= 8 { (a.min(b), a.max(b)) } else { (a, b) };
            push(&mut t, Point2::new(ta, 30.0), Point2::new(tb, 30.0));
        }
        Ok(repaired(t))
    }

    #[test]
    fn two_that_passed_each_other_while_speeding_up_are_not_taken_to_have_bounced() -> Result<()> {
        let (t, before) = overlap(true)?;
        let b = &t.tracks[1].observations;
        // B's track now carries on along A's former track from the frame they parted.
        let parted = 1 + 8 + 3;
        for f in parted..b.len() {
            assert_eq!(b[f].center, before[f], "frame {f}");
        }
        assert!(b[parted - 1].center != before[parted - 1]);
        // The mended A keeps moving right, B left, as before they met.
        let a_last = t.tracks[0].observations.last().and_then(|o| o.center);
        assert!(a_last.is_some_and(|c| c.x > 110.0), "{a_last:?}");
        // Markers that did turn beside each other stay as tracked.
        let (t, before) = overlap(false)?;
        assert_eq!(t.crossed(0, 1), None);
        let after: Vec<_> = t.tracks[0].observations.iter().map(|o| o.center).collect();
        assert_eq!(after, before);
        Ok(())
    }

    #[test]
    fn a_signature_is_not_replaced_by_a_wider_or_shifted_line() {
        let old = SwingLine {
            centre: Point2::new(60.0, 30.0),
            normal: Vector2::new(0.0, 1.0),
            sigma_px: 3.0,
            half_length_px: 15.0,
        };
        let tilted = Vector2::new(0.2, 0.98).normalize();
        assert!(refines(
            &old,
            &SwingLine {
                centre: Point2::new(62.0, 31.0),
                normal: tilted,
                ..old
            }
        ));
        assert!(!refines(
            &old,
            &SwingLine {
                sigma_px: 5.0,
                ..old
            }
        ));
        assert!(!refines(
            &old,
            &SwingLine {
                centre: Point2::new(60.0, 36.0),
                ..old
            }
        ));
        assert!(!refines(
            &old,
            &SwingLine {
                normal: Vector2::new(1.0, 0.0),
                ..old
            }
        ));
    }

    #[test]
    fn tracks_along_their_own_lines_stay() -> Result<()> {
        let (t, before) = run(false)?;
        let after: Vec<_> = t.tracks[0].observations.iter().map(|o| o.center).collect();
        assert_eq!(after, before);
        assert_eq!(t.markers[0].filter.position, Point2::new(100.0, 40.0));
        Ok(())
    }
}
