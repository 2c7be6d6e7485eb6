//! One frame's decisions after the quick pass: which results are accepted as tracked, and
//! what the frame teaches (look-alikes, how markers move together, merged markers, each
//! marker's observation).

use super::*;

impl Tracker {
    /// The quick pass's results accepted as `tracked` (confident, in the normal gate, alike,
    /// on the swing line when crowded, nobody else's place), nearest to their prediction
    /// first; the places they claim, and the markers left undecided for detection.
    pub(super) fn accept_quick(
        &self,
        quick: &[Option<Scored>],
        predictions: &[Point2<f64>],
    ) -> (Vec<Option<Found>>, Vec<Claim>, Vec<usize>) {
        let n = self.markers.len();
        let d2: Vec<f64> = (0..n)
            .map(|i| {
                let m = &self.markers[i];
                quick[i].as_ref().map_or(f64::INFINITY, |q| {
                    (q.measured.center - m.filter.position).norm_squared() / m.gate_var
                })
            })
            .collect();
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| d2[a].total_cmp(&d2[b]));
        let mut results: Vec<Option<Found>> = vec![None; n];
        let mut claimed: Vec<Claim> = Vec::new();
        let mut undecided = Vec::new();
        for &i in &order {
            let m = &self.markers[i];
            let Some(q) = quick[i] else {
                undecided.push(i);
                continue;
            };
            if !self.config.recovery {
                results[i] = Some((q.measured, TrackStatus::Tracked, q.context));
                continue;
            }
            let c = q.measured.center;
            // Identity is in doubt only after a jump of more than half a window, the reach of
            // plain mean-shift: a slower marker cannot have swapped with a look-alike.
            let jumped = (c - m.last_center).norm() > 0.5 * window_px(m);
            let familiar =
                !jumped || !m.context_informative() || q.context.is_none_or(|v| m.familiar(v));
            let accept = m.misses == 0
                && !m.held_by_still_weak()
                && !self.far_beyond_reach(i, c)
                && q.measured.confidence >= self.config.min_confidence
                && m.typical(q.measured.confidence)
                && d2[i] <= GATE_CHI2
                && !m.on_look_alike(&q.measured)
                && familiar
                && (!crowded(&self.markers, i)
                    || m.swing
                        .line()
                        .is_none_or(|l| l.offset(c).abs() <= LINE_ACCEPT_SPREADS))
                && !(self.config.exclusive
                    && (taken_part(&self.markers, i, q.measured, &claimed, quick)
                        || nearer_to_other(&self.markers, i, c, predictions)));
            if accept {
                claimed.push((i, q.measured.holds, c));
                results[i] = Some((q.measured, TrackStatus::Tracked, q.context));
            } else {
                undecided.push(i);
            }
        }
        (results, claimed, undecided)
    }

    /// What a found marker saw near it and was not is a look-alike to remember, unless it
    /// is some marker's place.
    pub(super) fn learn_look_alikes(
        &mut self,
        results: &[Option<Found>],
        rejected: &[Vec<(Point2<f64>, PixelRect)>],
        predictions: &[Point2<f64>],
    ) {
        let places_now: Vec<Point2<f64>> = predictions
            .iter()
            .copied()
            .chain(results.iter().flatten().map(|r| r.0.center))
            .collect();
        let frame = self.frames();
        for (i, result) in results.iter().enumerate() {
            let Some((q, _, _)) = result else { continue };
            let side = window_px(&self.markers[i]);
            for &(p, bounds) in &rejected[i] {
                if (p - q.center).norm() > side && places_now.iter().all(|c| (c - p).norm() > side)
                {
                    remember_distractor(&mut self.markers[i], p, bounds, side, frame);
                }
            }
        }
    }

    /// A detection two frames back, on a place where the marker once turned down a
    /// look-alike, that the track then left by a jump to run on from somewhere else, was
    /// that look-alike taken for one frame (a marker coming out from behind something is
    /// found first where its prediction ran on to): the frame is revised to `predicted`, at
    /// the place the two frames since lead back to. Only a look-alike counts as the
    /// culprit: right after a release or at a swing's end filmed at 15 fps a marker turns
    /// by several windows a frame, so a sharp turn alone says nothing.
    pub(super) fn revise_excursions(&mut self) {
        for (m, track) in self.markers.iter().zip(&mut self.tracks) {
            let obs = &mut track.observations;
            let Some(k) = obs.len().checked_sub(3) else {
                continue;
            };
            let (excursion, next, last) = (&obs[k], &obs[k + 1], &obs[k + 2]);
            if excursion.status != TrackStatus::Recovered
                || !next.status.found()
                || !last.status.found()
            {
                continue;
            }
            let (Some(p), Some(a), Some(b)) = (excursion.center, next.center, last.center) else {
                continue;
            };
            let side = window_px(m);
            let back = a - (b - a);
            let on_look_alike = m
                .distractors
                .iter()
                .any(|d| (d.at - p).norm() <= EXCURSION_LOOK_ALIKE_WINDOWS * side);
            if on_look_alike
                && (p - a).norm() > PARKED_JUMP_WINDOWS * side
                && (p - back).norm() > EXCURSION_WINDOWS * side
            {
                let o = &mut obs[k];
                o.status = TrackStatus::Predicted;
                o.confidence = 0.0;
                o.center = Some(back);
            }
        }
    }

    /// A marker whose track has stood still for [`PARKED_FRAMES`] frames, away from its home,
    /// on a place where it once turned down a look-alike, where detection threw it by a
    /// jump, or that it slid onto on [`SLID_FRAMES`] weak measurements in a row (mean-shift
    /// modes of half confidence drifting onto a look-alike at a swing's turn), is parked on
    /// a look-alike: a branch marker at rest stands at its home, and one
    /// held away from it got there by moving (followed by the quick pass, where no
    /// look-alike of its was seen while it was elsewhere). The place becomes a known static
    /// look-alike (the quick pass no longer accepts it, detection prices it), the frames since it came
    /// there are revised to `predicted`, and the marker is looked for where it swings.
    pub(super) fn learn_parked(&mut self) {
        for (m, track) in self.markers.iter_mut().zip(&mut self.tracks) {
            let Some(parked) = parked_at(m, &track.observations) else {
                continue;
            };
            let side = window_px(m);
            let near = (DISTRACTOR_RADIUS * side).max(2.0);
            let frame = track.observations.len().saturating_sub(1);
            if let Some(d) = m
                .distractors
                .iter_mut()
                .find(|d| (d.at - parked.at).norm() < near)
            {
                d.seen = d.seen.max(2);
                d.static_frame.get_or_insert(frame);
            } else if parked.jumped_in {
                remember_distractor(m, parked.at, parked.bounds, side, frame);
                remember_distractor(m, parked.at, parked.bounds, side, frame);
            } else {
                continue;
            }
            // What the track turned down while it stood there was seen from the wrong
            // place: most likely the marker itself, which must not count as a look-alike.
            m.distractors
                .retain(|d| d.first_frame < parked.since || (d.at - parked.at).norm() < near);
            // Those frames were the look-alike's: not found, and the marker is looked for
            // as one missing since then.
            for o in &mut track.observations[parked.since..] {
                o.status = TrackStatus::Predicted;
                o.confidence = 0.0;
            }
            m.misses = PARKED_FRAMES;
            m.last_status = TrackStatus::Predicted;
            // Where the marker is, is unknown; it swings about its home, within its reach.
            m.filter.position = m.home;
            m.filter.stop(side);
            m.filter.manoeuvre(m.reach_px.max(side));
        }
    }

    /// Markers found after a jump (more than half a window) that the markers they move with
    /// (one rig, one branch: displacements seen in proportion, see [`Coherence::gain`]) did
    /// not make, and where those say the marker went. Of the [`COHERENT_NEAREST`] nearest
    /// such markers found in this frame and the last on a likeness at most [`WITNESS_SLACK`]
    /// less sure than the marker's own (at least [`COHERENT_WITNESSES`]), more
    /// than half give this marker a displacement (theirs times the gain) more than
    /// [`INCOHERENT_WINDOWS`] (and more than [`GAIN_TOLERANCE`] of that displacement) from
    /// the one it was found with; the median of those is the answer. With a single
    /// witness, it must disagree by [`LONE_WITNESS_WINDOWS`] and have been found on a
    /// likeness at least [`LONE_WITNESS_MARGIN`] surer than the target's. The case: a row of look-alike targets that jumps, where the prediction of one
    /// lands on its neighbour's target, which then passes every test. The nearest only,
    /// since a rig's far parts move differently; a majority rather than agreement, since a
    /// witness may have been fooled the same way. Gray targets only: colour markers are
    /// told apart by colour and swing lines, and markers on branches that were pulled and
    /// released together move in proportion for a while and then apart (on the stress
    /// sequences' `jumps` condition the rule cost 0.4 points).
    pub(super) fn incoherent(&self, results: &[Option<Found>]) -> Vec<(usize, Vector2<f64>)> {
        let n = self.markers.len();
        let moved = self.moved(results);
        self.moved_targets(results, &moved, 0.5)
            .into_iter()
            .filter_map(|(i, d, own)| {
                let m = &self.markers[i];
                let side = window_px(m);
                let last = m.last_center;
                // What each says this marker's displacement was, and how sure it was found;
                // only those found on a likeness about as sure as this one's.
                let mut near: Vec<(f64, Vector2<f64>, f64)> = (0..n)
                    .filter(|&j| j != i)
                    .filter_map(|j| {
                        let gain = self.coherence[i * n + j].gain(side)?;
                        let w = moved[j]?;
                        let sure = results[j].as_ref()?.0.confidence;
                        if sure < own - WITNESS_SLACK {
                            return None;
                        }
                        Some(((self.markers[j].last_center - last).norm(), gain * w, sure))
                    })
                    .collect();
                near.sort_by(|a, b| a.0.total_cmp(&b.0));
                near.truncate(COHERENT_NEAREST);
                // A gain is known to within a share of what it gives.
                let apart = |w: Vector2<f64>, windows: f64| {
                    (w - d).norm() > (windows * side).max(GAIN_TOLERANCE * w.norm())
                };
                let mut otherwise: Vec<Vector2<f64>> = near
                    .iter()
                    .map(|w| w.1)
                    .filter(|&w| apart(w, INCOHERENT_WINDOWS))
                    .collect();
                let majority = near.len() >= COHERENT_WITNESSES && 2 * otherwise.len() > near.len();
                // One witness against one target: the one found on the weaker likeness
                // gives way, if they disagree by far.
                let lone = match near.as_slice() {
                    [(_, w, sure)] => {
                        apart(*w, LONE_WITNESS_WINDOWS) && *sure >= own + LONE_WITNESS_MARGIN
                    }
                    _ => false,
                };
                if !majority && !lone {
                    return None;
                }
                otherwise.sort_by(|a, b| a.x.total_cmp(&b.x));
                let x = otherwise[otherwise.len() / 2].x;
                otherwise.sort_by(|a, b| a.y.total_cmp(&b.y));
                let y = otherwise[otherwise.len() / 2].y;
                Some((i, Vector2::new(x, y)))
            })
            .collect()
    }

    /// Gray targets found after a move (more than [`AGAINST_WINDOWS`]) against the direction in
    /// which every one of their [`COHERENT_NEAREST`] nearest rig-mates jumped (each more
    /// than half a window, found on a likeness at least [`LONE_WITNESS_MARGIN`] surer),
    /// where no gain is known yet: the markers have only been seen moving the same way, by
    /// amounts too small or too unequal for [`Coherence::gain`] (the first frame of a
    /// release, where a rig's far rows barely move). By at least [`AGAINST_WINDOWS`] against
    /// it; with the direction of the witnesses' mean displacement.
    pub(super) fn against_the_rig(&self, results: &[Option<Found>]) -> Vec<(usize, Vector2<f64>)> {
        let n = self.markers.len();
        let moved = self.moved(results);
        self.moved_targets(results, &moved, AGAINST_WINDOWS)
            .into_iter()
            .filter_map(|(i, d, own)| {
                let m = &self.markers[i];
                let side = window_px(m);
                let known_gain = (0..n).any(|j| {
                    j != i && moved[j].is_some() && self.coherence[i * n + j].gain(side).is_some()
                });
                if known_gain {
                    return None;
                }
                let last = m.last_center;
                let mut near: Vec<(f64, Vector2<f64>)> = (0..n)
                    .filter(|&j| j != i && self.coherence[i * n + j].same_way())
                    .filter_map(|j| {
                        let w = moved[j].filter(|w| w.norm() > 0.5 * side)?;
                        let sure = results[j].as_ref()?.0.confidence;
                        (sure >= own + LONE_WITNESS_MARGIN)
                            .then(|| ((self.markers[j].last_center - last).norm(), w))
                    })
                    .collect();
                near.sort_by(|a, b| a.0.total_cmp(&b.0));
                near.truncate(COHERENT_NEAREST);
                let against = |w: &Vector2<f64>| d.dot(&w.normalize()) < -AGAINST_WINDOWS * side;
                if near.is_empty() || !near.iter().all(|(_, w)| against(w)) {
                    return None;
                }
                let mean: Vector2<f64> = near.iter().map(|(_, w)| w.normalize()).sum();
                Some((i, mean.normalize()))
            })
            .collect()
    }

    /// The gray targets whose move their rig-mates say is wrong, and where they say each
    /// went: [`Tracker::incoherent`], then [`Tracker::against_the_rig`] for the others.
    pub(super) fn flags(&self, results: &[Option<Found>]) -> Vec<Flag> {
        let mut flags: Vec<Flag> = self
            .incoherent(results)
            .into_iter()
            .map(|(marker, moved)| Flag {
                marker,
                went: Went::By(moved),
            })
            .collect();
        for (marker, direction) in self.against_the_rig(results) {
            if flags.iter().all(|f| f.marker != marker) {
                flags.push(Flag {
                    marker,
                    went: Went::Along(direction),
                });
            }
        }
        flags
    }

    /// Gray targets found in this frame and the last that moved more than `windows` of
    /// their window: each with its displacement (`moved`, from [`Tracker::moved`]) and the
    /// confidence it was found with.
    fn moved_targets(
        &self,
        results: &[Option<Found>],
        moved: &[Option<Vector2<f64>>],
        windows: f64,
    ) -> Vec<(usize, Vector2<f64>, f64)> {
        self.markers
            .iter()
            .enumerate()
            .filter(|(_, m)| m.template.is_some())
            .filter_map(|(i, m)| {
                let d = moved[i].filter(|d| d.norm() > windows * window_px(m))?;
                Some((i, d, results[i].as_ref()?.0.confidence))
            })
            .collect()
    }

    /// Each marker's displacement since the last frame, where it was found in both.
    fn moved(&self, results: &[Option<Found>]) -> Vec<Option<Vector2<f64>>> {
        results
            .iter()
            .zip(&self.markers)
            .map(|(r, m)| {
                r.as_ref()
                    .filter(|_| m.last_status.found())
                    .map(|(q, _, _)| q.center - m.last_center)
            })
            .collect()
    }

    /// How alike the markers found in this frame and the last have moved.
    pub(super) fn learn_coherence(&mut self, results: &[Option<Found>]) {
        let n = self.markers.len();
        let moved = self.moved(results);
        for (a, da) in moved.iter().enumerate() {
            for (b, db) in moved.iter().enumerate().skip(a + 1) {
                if let (Some(da), Some(db)) = (da, db) {
                    self.coherence[a * n + b].learn(*da, *db);
                    self.coherence[b * n + a].learn(*db, *da);
                }
            }
        }
    }

    /// A marker not found where a found marker of its look now is has merged with it (two
    /// markers of one colour crossing): it moves with that marker until they part, rather
    /// than coasting away and being lost.
    pub(super) fn merged_markers(
        &self,
        results: &[Option<Found>],
        predictions: &[Point2<f64>],
    ) -> Vec<bool> {
        let n = self.markers.len();
        (0..n)
            .map(|i| {
                let m = &self.markers[i];
                let reach = MERGED_WINDOWS * window_px(m);
                results[i].is_none()
                    && (0..n).any(|j| {
                        j != i
                            && same_look(m, &self.markers[j])
                            && results[j]
                                .as_ref()
                                .is_some_and(|(q, _, _)| (q.center - predictions[i]).norm() < reach)
                    })
            })
            .collect()
    }

    /// Each marker's observation of this frame from its result (found, merged or missed),
    /// with what a found marker teaches its appearance, surroundings and template.
    pub(super) fn record(
        &mut self,
        frame: &RgbImage,
        depth: Option<&DepthView<'_>>,
        results: Vec<Option<Found>>,
        merged: &[bool],
    ) {
        let (width, height) = (self.width, self.height);
        let frame_index = self.tracks.first().map_or(0, |t| t.observations.len()) as u64;
        for (i, result) in results.into_iter().enumerate() {
            let m = &mut self.markers[i];
            let observation = match result {
                Some((q, status, context)) => {
                    let status = if status == TrackStatus::Tracked && !m.last_status.found() {
                        TrackStatus::Recovered
                    } else {
                        status
                    };
                    let mut o = m.found(q, status, &self.config, depth, frame_index);
                    if o.confidence < TRUSTED_CONFIDENCE || q.cut {
                        // Followed, but not a place to stand behind (too unlike the marker,
                        // or a blob the quick pass's region cut): reported as an estimate.
                        o.status = TrackStatus::Predicted;
                        m.weak_run += 1;
                        let near = WEAK_STILL_WINDOWS * window_px(m);
                        m.weak_place = Some(match m.weak_place {
                            Some((at, still)) if (q.center - at).norm() <= near => {
                                (q.center, still + 1)
                            }
                            _ => (q.center, 1),
                        });
                    } else {
                        m.weak_run = 0;
                        m.weak_place = None;
                    }
                    m.learn_appearance(q.confidence, context);
                    if let (Some(_), Some(t)) = (context, m.context.as_mut()) {
                        t.update(frame, q.center, CONTEXT_RATE, &mut self.patch);
                    }
                    if let Some(t) = m.template.as_mut()
                        && status == TrackStatus::Tracked
                        && q.confidence >= TEMPLATE_UPDATE_CONFIDENCE
                    {
                        t.update(frame, q.center, TEMPLATE_RATE, &mut self.patch);
                    }
                    o
                }
                None if merged[i] => m.merged((width, height)),
                None => m.missed(&self.config, (width, height)),
            };
            self.tracks[i].observations.push(observation);
        }
    }
}

/// A place a track has stood still on.
struct Parked {
    /// The mean of its centres there.
    at: Point2<f64>,
    /// The last window there.
    bounds: PixelRect,
    /// Whether detection took it there by a jump of more than [`PARKED_JUMP_WINDOWS`]
    /// windows, or straight after frames the marker was missing in, to a place off its
    /// swing line (rather than the quick pass following it there).
    jumped_in: bool,
    /// The first frame of the stay: where detection threw the track, when that was before
    /// the last [`PARKED_FRAMES`] frames, else the first of them.
    since: usize,
}

/// Weak measurements in a row just before a stay that make it one the track slid into.
const SLID_FRAMES: usize = 3;

/// Where the track has stood still, found on at least [`PARKED_MIN_FOUND`] of the last
/// [`PARKED_FRAMES`] frames, when that is away from the marker's home.
fn parked_at(m: &MarkerState, obs: &[Observation]) -> Option<Parked> {
    let start = obs.len().checked_sub(PARKED_FRAMES)?;
    let found = || {
        obs[start..]
            .iter()
            .filter(|o| followed(o))
            .filter_map(|o| o.center.map(|c| (c, o.window)))
    };
    let (count, sum) = found().fold((0_u32, Vector2::zeros()), |(n, s), (c, _)| {
        (n + 1, s + c.coords)
    });
    if (count as usize) < PARKED_MIN_FOUND {
        return None;
    }
    let at = Point2::from(sum / f64::from(count));
    let side = window_px(m);
    let still = found().all(|(c, _)| (c - at).norm() <= PARKED_PX);
    if !still {
        return None;
    }
    // Frame `k` was a throw: found by detection more than `PARKED_JUMP_WINDOWS` from where
    // the track was last (before a frame it was lost in, the last place it had).
    let thrown = |k: usize| {
        let o = &obs[k];
        followed(o)
            && o.status != TrackStatus::Tracked
            && o.center.is_some_and(|b| {
                obs[..k]
                    .iter()
                    .rev()
                    .take(PARKED_LOOKBACK_FRAMES)
                    .find_map(|p| p.center)
                    .is_some_and(|a| (b - a).norm() > PARKED_JUMP_WINDOWS * side)
            })
    };
    // The stay began where the track came to this place: possibly before these frames, when
    // the first of a still stretch jittered by more than `PARKED_PX` (a look-alike measured
    // through noise and JPEG artefacts).
    // Up to `PARKED_EXCURSION_FRAMES` frames measured off the place in the middle of a stay
    // (a piece of something else taken by detection, then the look-alike again) do not end
    // it.
    let stay_px = PARKED_STAY_WINDOWS * side;
    let away = |k: usize| obs[k].center.is_none_or(|c| (c - at).norm() > stay_px);
    let entered = (obs.len().saturating_sub(PARKED_LOOKBACK_FRAMES).max(1)..obs.len())
        .rev()
        .find(|&k| (k.saturating_sub(PARKED_EXCURSION_FRAMES + 1)..k).all(away));
    let off_line = m
        .signature
        .is_some_and(|s| s.offset(at) > PARKED_OFF_LINE_SPREADS);
    // A track that came to the place straight from frames the marker was missing in (out
    // of the frame, hidden) was taken there by detection as much as one thrown there; off
    // the marker's own swing line the place is not one it is held on in a pull.
    // So was one that slid there on weak measurements (half-confidence mean-shift modes
    // drifting onto a look-alike at a swing's turn).
    let slid_in =
        |k: usize| k >= SLID_FRAMES && obs[k - SLID_FRAMES..k].iter().all(weakly_followed);
    let back_from_loss = |k: usize| (off_line && k >= 1 && !followed(&obs[k - 1])) || slid_in(k);
    let thrown_before = entered.filter(|&k| k < start && (thrown(k) || back_from_loss(k)));
    let jumped_in = thrown_before.is_some()
        || (start.max(1)..obs.len()).any(thrown)
        || entered.is_some_and(back_from_loss);
    // Near its home a marker may be held still (a child carried by its parent's pull), but
    // not on a look-alike it knew as static before the track came there, nor far off the
    // line it swings along (a pull is held on that line).
    let came = entered.unwrap_or(start);
    let known_before = m.distractors.iter().any(|d| {
        (d.at - at).norm() < (DISTRACTOR_RADIUS * side).max(2.0)
            && d.static_frame.is_some_and(|f| f < came)
    });
    let from_home = (at - m.home).norm();
    if from_home <= HOME_NEAR_WINDOWS * side
        && !((known_before || off_line) && from_home > LOOK_ALIKE_FROM_HOME_WINDOWS * side)
    {
        return None;
    }
    Some(Parked {
        at,
        bounds: found()
            .next_back()
            .map_or(PixelRect::centered_at(at, m.size.0, m.size.1), |f| f.1),
        jumped_in,
        since: thrown_before.unwrap_or(start),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::two_red_markers;

    /// Two red markers, and A's window side and home.
    fn setup() -> Result<(Tracker, f64, Point2<f64>)> {
        let t = two_red_markers()?;
        let (side, home) = (window_px(&t.markers[0]), t.markers[0].home);
        Ok((t, side, home))
    }

    /// A's track: `frames` frames found at `at`, after frame 0.
    fn park(t: &mut Tracker, at: Point2<f64>, frames: usize) {
        for _ in 0..frames {
            for (k, track) in t.tracks.iter_mut().enumerate() {
                let p = if k == 0 { at } else { t.markers[k].home };
                track.observations.push(Observation {
                    center: Some(p),
                    window: PixelRect::centered_at(p, 11, 11),
                    status: TrackStatus::Tracked,
                    confidence: 0.95,
                });
            }
        }
    }

    /// A's observations from `thrown_at` on were revised to `predicted`, the one before
    /// it was not.
    fn assert_revised_from(t: &Tracker, thrown_at: usize) {
        let obs = &t.tracks[0].observations;
        assert!(
            obs[thrown_at..]
                .iter()
                .all(|o| o.status == TrackStatus::Predicted)
        );
        assert_eq!(obs[thrown_at - 1].status, TrackStatus::Tracked);
    }

    /// True when every observation of track `k` after the first frame is `tracked`.
    fn all_tracked(t: &Tracker, k: usize) -> bool {
        t.tracks[k]
            .observations
            .iter()
            .skip(1)
            .all(|o| o.status == TrackStatus::Tracked)
    }

    #[test]
    fn a_measurement_too_unlike_the_marker_is_followed_but_not_reported_found() -> Result<()> {
        let (mut t, side, home) = setup()?;
        let frame = RgbImage::new(t.width, t.height);
        let at = |dx: f64, confidence: f64| Measured {
            center: Point2::new(home.x + dx, home.y),
            window: PixelRect::centered_at(home, 11, 11),
            holds: PixelRect::centered_at(home, 11, 11),
            confidence,
            moments: None,
            cut: false,
            split: false,
            misfit: 0.0,
            spread: None,
        };
        let b = t.markers[1].home;
        let b_found = |confidence| {
            let mut q = at(0.0, confidence);
            q.center = b;
            Some((q, TrackStatus::Tracked, None))
        };
        let normal_gate = t.gate(0).radius_px;
        for (dx, confidence) in [
            (0.3 * side, TRUSTED_CONFIDENCE - 0.05),
            (0.6 * side, TRUSTED_CONFIDENCE),
        ] {
            let results = vec![
                Some((at(dx, confidence), TrackStatus::Tracked, None)),
                b_found(0.9),
            ];
            t.record(&frame, None, results, &[false, false]);
            // After the weak one the search widens as after a miss (the place followed may
            // be a still look-alike while the marker swings on); the trusted one ends that.
            let gate = t.gate(0).radius_px;
            if confidence < TRUSTED_CONFIDENCE {
                assert_eq!(t.markers[0].searching(), 1);
                assert!(gate > 1.2 * normal_gate, "{gate} {normal_gate}");
            } else {
                assert_eq!(t.markers[0].searching(), 0);
            }
        }
        let obs = &t.tracks[0].observations;
        let (weak, trusted) = (obs[obs.len() - 2], obs[obs.len() - 1]);
        // The weak one is an estimate: not found, its own confidence (not 0: not coasting),
        // and the place the tracker followed.
        assert_eq!(weak.status, TrackStatus::Predicted);
        assert!((weak.confidence - (TRUSTED_CONFIDENCE - 0.05)).abs() < 1e-12);
        assert_eq!(weak.center, Some(Point2::new(home.x + 0.3 * side, home.y)));
        // Followed all the same: the next, trusted one is tracked, not recovered.
        assert_eq!(trusted.status, TrackStatus::Tracked);
        assert_eq!(
            trusted.center,
            Some(Point2::new(home.x + 0.6 * side, home.y))
        );
        Ok(())
    }

    #[test]
    fn a_part_of_a_remembered_look_alike_is_that_look_alike_wherever_it_is_centred() -> Result<()> {
        let (mut t, side, home) = setup()?;
        // A look-alike whose 14x30 px box was seen twice where it is, centred low in it (a
        // twig cut it, and its lower part was the blob then).
        let box_of = PixelRect::new((home.x + 4.0 * side) as i32, (home.y + side) as i32, 14, 30);
        let seen_at = Point2::new(f64::from(box_of.x) + 7.0, f64::from(box_of.y) + 20.0);
        for frame in 0..2 {
            remember_distractor(&mut t.markers[0], seen_at, box_of, side, frame);
        }
        let measured = |holds: PixelRect| Measured {
            center: Point2::new(
                f64::from(holds.x) + 0.5 * f64::from(holds.width),
                f64::from(holds.y) + 0.5 * f64::from(holds.height),
            ),
            window: holds,
            holds,
            confidence: 0.98,
            moments: None,
            cut: false,
            split: false,
            misfit: 0.0,
            spread: None,
        };
        // Its upper part: centred 10 px from the remembered centre, but inside its box.
        let upper = measured(PixelRect::new(box_of.x, box_of.y, 13, 18));
        assert!(!t.markers[0].on_distractor(upper.center));
        assert!(t.markers[0].on_look_alike(&upper));
        // A marker passing over it makes a blob reaching out of the box: not the look-alike.
        let passing = measured(PixelRect::new(box_of.x - 8, box_of.y, 20, 18));
        assert!(!t.markers[0].on_look_alike(&passing));
        // A marker-sized blob inside a much larger remembered box is not taken for a part.
        let small = measured(PixelRect::new(box_of.x + 2, box_of.y + 2, 10, 10));
        assert!(!t.markers[0].on_look_alike(&small));
        Ok(())
    }

    #[test]
    fn a_track_standing_on_a_once_seen_look_alike_away_from_home_is_parked() -> Result<()> {
        let (mut t, side, home) = setup()?;
        let look_alike = Point2::new(home.x + 4.0 * side, home.y + 2.0);
        let bounds = PixelRect::centered_at(look_alike, 11, 11);
        remember_distractor(&mut t.markers[0], look_alike, bounds, side, 0);
        assert!(!t.markers[0].on_distractor(look_alike));
        // Standing there for fewer frames than the rule asks: a swing's turn.
        park(&mut t, look_alike, PARKED_FRAMES - 1);
        t.learn_parked();
        assert!(!t.markers[0].on_distractor(look_alike));
        park(&mut t, look_alike, 1);
        t.learn_parked();
        // A known static look-alike now; those frames are no longer reported found, and A
        // is looked for about its home.
        assert!(t.markers[0].on_distractor(look_alike));
        let obs = &t.tracks[0].observations;
        assert!(
            obs[obs.len() - PARKED_FRAMES..]
                .iter()
                .all(|o| o.status == TrackStatus::Predicted && o.confidence == 0.0)
        );
        assert_eq!(t.markers[0].misses, PARKED_FRAMES);
        assert_eq!(t.markers[0].filter.position, home);
        // B, standing still at its home all along, is untouched.
        assert!(all_tracked(&t, 1));
        Ok(())
    }

    #[test]
    fn a_track_that_detection_threw_onto_a_still_place_is_parked_there() -> Result<()> {
        let (mut t, side, home) = setup()?;
        let there = Point2::new(home.x + 5.0 * side, home.y + 3.0);
        park(&mut t, home, 3);
        park(&mut t, there, PARKED_FRAMES);
        // Taken there by detection, from home; two of the frames there not found.
        let len = t.tracks[0].observations.len();
        let obs = &mut t.tracks[0].observations;
        obs[len - PARKED_FRAMES].status = TrackStatus::Recovered;
        for o in &mut obs[len - 3..len - 1] {
            o.status = TrackStatus::Predicted;
        }
        t.learn_parked();
        assert!(t.markers[0].on_distractor(there));
        assert_eq!(t.markers[0].misses, PARKED_FRAMES);
        // Followed there by the quick pass instead (a pull held there): not parked.
        let (mut t, _, _) = setup()?;
        park(&mut t, home, 3);
        park(&mut t, there, PARKED_FRAMES);
        t.learn_parked();
        assert!(!t.markers[0].on_distractor(there));
        assert_eq!(t.markers[0].misses, 0);
        // Lost for a frame (no centre) before detection found it there: the throw is
        // measured from the last place the track had.
        let (mut t, _, _) = setup()?;
        park(&mut t, home, 4);
        park(&mut t, there, PARKED_FRAMES);
        let len = t.tracks[0].observations.len();
        let obs = &mut t.tracks[0].observations;
        obs[len - PARKED_FRAMES - 1].center = None;
        obs[len - PARKED_FRAMES - 1].status = TrackStatus::Lost;
        obs[len - PARKED_FRAMES].status = TrackStatus::Recovered;
        t.learn_parked();
        assert!(t.markers[0].on_distractor(there));
        assert_eq!(t.markers[0].misses, PARKED_FRAMES);
        Ok(())
    }

    #[test]
    fn a_track_that_slid_onto_a_still_place_on_weak_measurements_is_parked_there() -> Result<()> {
        // From beside its home, A's track slides 8 px a frame on `weak` measurements
        // (half-confidence mean-shift modes, reported predicted) onto a place 4 windows off,
        // then stands there, found sure.
        let slid = |weak: usize| -> Result<Tracker> {
            let (mut t, side, home) = setup()?;
            let there = Point2::new(home.x + 4.0 * side, home.y - 2.0 * side);
            park(&mut t, home, 3);
            for k in (1..=SLID_FRAMES).rev() {
                park(&mut t, there + Vector2::new(0.0, 8.0 * k as f64), 1);
            }
            park(&mut t, there, PARKED_FRAMES);
            let len = t.tracks[0].observations.len();
            let slide = len - PARKED_FRAMES - weak;
            for o in &mut t.tracks[0].observations[slide..len - PARKED_FRAMES] {
                o.status = TrackStatus::Predicted;
                o.confidence = 0.5;
            }
            t.learn_parked();
            Ok(t)
        };
        let t = slid(SLID_FRAMES)?;
        assert_eq!(t.markers[0].misses, PARKED_FRAMES);
        let len = t.tracks[0].observations.len();
        assert_revised_from(&t, len - PARKED_FRAMES - SLID_FRAMES);
        // One weak frame fewer (a marker dimmed for a moment, then held in a pull): not
        // parked.
        let t = slid(SLID_FRAMES - 1)?;
        assert_eq!(t.markers[0].misses, 0);
        Ok(())
    }

    #[test]
    fn a_track_thrown_near_home_but_far_off_the_swing_line_is_parked() -> Result<()> {
        // A swings along x through its home (spread across the line 3 px); detection throws
        // its track from 1.5 windows along the line to 1.5 windows above home (a jump of
        // 2.1 windows), within the home's reach but 5 spreads off the line.
        let thrown = |on_line: bool| -> Result<Tracker> {
            let (mut t, side, home) = setup()?;
            t.markers[0].signature = Some(crate::swing::SwingLine {
                centre: home,
                normal: Vector2::new(0.0, 1.0),
                sigma_px: 3.0,
                half_length_px: 2.0 * side,
            });
            let from = Point2::new(home.x + 1.5 * side, home.y);
            let there = if on_line {
                Point2::new(home.x - 0.7 * side, home.y)
            } else {
                Point2::new(home.x, home.y - 1.5 * side)
            };
            park(&mut t, from, 3);
            park(&mut t, there, PARKED_FRAMES);
            let len = t.tracks[0].observations.len();
            t.tracks[0].observations[len - PARKED_FRAMES].status = TrackStatus::Recovered;
            t.learn_parked();
            Ok(t)
        };
        let last = |t: &Tracker| t.tracks[0].observations.last().map(|o| o.status);
        let t = thrown(false)?;
        assert_eq!(t.markers[0].misses, PARKED_FRAMES);
        assert_eq!(last(&t), Some(TrackStatus::Predicted));
        // Thrown as far onto the line itself (a pull held there): not parked.
        let t = thrown(true)?;
        assert_eq!(t.markers[0].misses, 0);
        assert_eq!(last(&t), Some(TrackStatus::Tracked));
        Ok(())
    }

    #[test]
    fn a_track_taken_off_its_line_straight_after_the_marker_went_missing_is_parked() -> Result<()> {
        // A swings along x through its home; it runs out of sight 5 windows right of home
        // (three frames coasting on, not measured), and the track is taken 1.5 windows
        // from there (under the throw's 2 windows) to a still place 1.4 windows above the
        // line, or on it.
        let taken = |on_line: bool| -> Result<Tracker> {
            let (mut t, side, home) = setup()?;
            t.markers[0].signature = Some(crate::swing::SwingLine {
                centre: home,
                normal: Vector2::new(0.0, 1.0),
                sigma_px: 3.0,
                half_length_px: 6.0 * side,
            });
            let gone = Point2::new(home.x + 5.0 * side, home.y);
            let there = if on_line {
                Point2::new(gone.x - 1.5 * side, home.y)
            } else {
                Point2::new(gone.x - 0.5 * side, home.y - 1.4 * side)
            };
            park(&mut t, gone, 4);
            let len = t.tracks[0].observations.len();
            for o in &mut t.tracks[0].observations[len - 3..] {
                o.status = TrackStatus::Predicted;
                o.confidence = 0.0;
            }
            park(&mut t, there, PARKED_FRAMES);
            let len = t.tracks[0].observations.len();
            t.tracks[0].observations[len - PARKED_FRAMES].status = TrackStatus::Recovered;
            t.learn_parked();
            Ok(t)
        };
        let t = taken(false)?;
        assert_eq!(t.markers[0].misses, PARKED_FRAMES);
        let obs = &t.tracks[0].observations;
        assert!(
            obs[obs.len() - PARKED_FRAMES..]
                .iter()
                .all(|o| o.status == TrackStatus::Predicted && o.confidence == 0.0)
        );
        // On its line (a pull held there once the marker is back in view): not parked.
        let t = taken(true)?;
        assert_eq!(t.markers[0].misses, 0);
        assert!(
            t.tracks[0].observations[t.tracks[0].observations.len() - PARKED_FRAMES + 1..]
                .iter()
                .all(|o| o.status == TrackStatus::Tracked)
        );
        Ok(())
    }

    #[test]
    fn a_track_thrown_onto_a_place_it_jittered_on_at_first_is_parked_from_the_throw() -> Result<()>
    {
        let (mut t, side, home) = setup()?;
        let there = Point2::new(home.x + 6.0 * side, home.y + 2.0);
        park(&mut t, home, 3);
        // Thrown there by detection; its first frames there jitter by more than the still
        // test allows, so the last `PARKED_FRAMES` frames no longer hold the throw.
        let jitter = Point2::new(there.x + 1.5 * PARKED_PX, there.y);
        park(&mut t, jitter, 3);
        park(&mut t, there, PARKED_FRAMES - 1);
        let len = t.tracks[0].observations.len();
        let thrown_at = len - PARKED_FRAMES - 2;
        t.tracks[0].observations[thrown_at].status = TrackStatus::Recovered;
        t.learn_parked();
        assert!(!t.markers[0].on_distractor(there));
        park(&mut t, there, 1);
        t.learn_parked();
        assert!(t.markers[0].on_distractor(there));
        // Every frame since the throw was the look-alike's, not only the last eight.
        assert_revised_from(&t, thrown_at);
        // The same stay reached by the quick pass (no throw) is a pull held there.
        let (mut t, _, _) = setup()?;
        park(&mut t, home, 3);
        park(&mut t, jitter, 3);
        park(&mut t, there, PARKED_FRAMES);
        t.learn_parked();
        assert!(!t.markers[0].on_distractor(there));
        assert!(all_tracked(&t, 0));
        Ok(())
    }

    #[test]
    fn a_frame_measured_off_a_stay_does_not_hide_the_throw_that_began_it() -> Result<()> {
        // Thrown there by detection, three frames there, `away` frames a window off it (a
        // piece of something else), then the look-alike again for `PARKED_FRAMES` frames.
        let stay = |away: usize| -> Result<(Tracker, usize, Point2<f64>)> {
            let (mut t, side, home) = setup()?;
            let there = Point2::new(home.x + 5.0 * side, home.y + 2.0);
            park(&mut t, home, 3);
            let thrown_at = t.tracks[0].observations.len();
            park(&mut t, there, 3);
            park(&mut t, Point2::new(there.x + side, there.y), away);
            park(&mut t, there, PARKED_FRAMES);
            t.tracks[0].observations[thrown_at].status = TrackStatus::Recovered;
            t.learn_parked();
            Ok((t, thrown_at, there))
        };
        let (t, thrown_at, there) = stay(1)?;
        assert!(t.markers[0].on_distractor(there));
        assert_revised_from(&t, thrown_at);
        // Away for longer: the track left and came back by the quick pass, a new stay.
        let (t, _, there) = stay(PARKED_EXCURSION_FRAMES + 1)?;
        assert!(!t.markers[0].on_distractor(there));
        assert_eq!(t.markers[0].misses, 0);
        assert!(
            t.tracks[0]
                .observations
                .iter()
                .all(|o| o.status != TrackStatus::Predicted)
        );
        Ok(())
    }

    /// A's track: found at each of `places` in turn, detection's first, the quick pass's
    /// after; then the excursion rule.
    fn found_at(t: &mut Tracker, places: &[Point2<f64>]) {
        for (k, &p) in places.iter().enumerate() {
            park(t, p, 1);
            if k == 0 {
                let obs = &mut t.tracks[0].observations;
                let last = obs.len() - 1;
                obs[last].status = TrackStatus::Recovered;
            }
            t.revise_excursions();
        }
    }

    #[test]
    fn a_detection_the_track_jumped_away_from_for_good_is_revised() -> Result<()> {
        let (mut t, side, home) = setup()?;
        park(&mut t, home, 2);
        // Detection took A onto a look-alike 5 windows off, one it had turned down before;
        // the next two frames find it running on from where those two lead back to, 1
        // window a frame.
        let look_alike = Point2::new(home.x + 5.0 * side, home.y);
        let step = Vector2::new(0.0, side);
        let seen = Point2::new(look_alike.x + 0.4 * side, look_alike.y);
        let bounds = PixelRect::centered_at(seen, 11, 11);
        remember_distractor(&mut t.markers[0], seen, bounds, side, 0);
        found_at(&mut t, &[look_alike, home + step, home + 2.0 * step]);
        let o = t.tracks[0].observations[3];
        assert_eq!(o.status, TrackStatus::Predicted);
        assert_eq!(o.confidence, 0.0);
        assert_eq!(o.center, Some(home));
        // The same jump where no look-alike was seen (a release, a swing's end at 15 fps)
        // is not revised, nor is a jump onto the look-alike the frames after continue from.
        let (mut t, _, _) = setup()?;
        park(&mut t, home, 2);
        found_at(&mut t, &[look_alike, home + step, home + 2.0 * step]);
        assert_eq!(t.tracks[0].observations[3].status, TrackStatus::Recovered);
        let (mut t, _, _) = setup()?;
        park(&mut t, home, 2);
        remember_distractor(&mut t.markers[0], seen, bounds, side, 0);
        found_at(
            &mut t,
            &[look_alike, look_alike + step, look_alike + 2.0 * step],
        );
        assert_eq!(t.tracks[0].observations[3].status, TrackStatus::Recovered);
        Ok(())
    }

    #[test]
    fn a_track_standing_near_home_on_a_look_alike_known_before_it_came_is_parked() -> Result<()> {
        let (mut t, side, home) = setup()?;
        // A static look-alike (seen twice) a window and a half above A's home, inside the
        // home's reach: known before the track comes there.
        let look_alike = Point2::new(home.x, home.y - 1.5 * side);
        let bounds = PixelRect::centered_at(look_alike, 11, 11);
        remember_distractor(&mut t.markers[0], look_alike, bounds, side, 0);
        remember_distractor(&mut t.markers[0], look_alike, bounds, side, 0);
        park(&mut t, home, 2);
        // The track stands on it; meanwhile the marker at home is turned down and
        // remembered as a look-alike (twice: static).
        park(&mut t, look_alike, PARKED_FRAMES);
        let at_home = PixelRect::centered_at(home, 11, 11);
        remember_distractor(&mut t.markers[0], home, at_home, side, 5);
        remember_distractor(&mut t.markers[0], home, at_home, side, 6);
        assert!(t.markers[0].on_distractor(home));
        t.learn_parked();
        // Parked: the frames there are estimates, and what it turned down from there is
        // forgotten, so that the marker at home is its own again.
        assert_eq!(t.markers[0].misses, PARKED_FRAMES);
        assert_eq!(t.tracks[0].observations[3].status, TrackStatus::Predicted);
        assert!(!t.markers[0].on_distractor(home));
        // The same stay on a look-alike first seen there once the track stood on it is the
        // marker held near home (a child carried by its parent's pull): not parked.
        let (mut t, _, _) = setup()?;
        park(&mut t, home, 2);
        park(&mut t, look_alike, PARKED_FRAMES);
        remember_distractor(&mut t.markers[0], look_alike, bounds, side, 4);
        remember_distractor(&mut t.markers[0], look_alike, bounds, side, 5);
        t.learn_parked();
        assert_eq!(t.markers[0].misses, 0);
        assert!(all_tracked(&t, 0));
        Ok(())
    }

    #[test]
    fn standing_still_at_home_or_where_no_look_alike_was_seen_is_not_parked() -> Result<()> {
        let (mut t, side, home) = setup()?;
        // A look-alike seen once right by its home: standing there is resting.
        let by_home = Point2::new(home.x + 1.0, home.y + 1.0);
        remember_distractor(
            &mut t.markers[0],
            by_home,
            PixelRect::centered_at(by_home, 11, 11),
            side,
            0,
        );
        park(&mut t, by_home, 2 * PARKED_FRAMES);
        t.learn_parked();
        assert!(!t.markers[0].on_distractor(by_home));
        // Held still away from home where no look-alike was seen: a pull being held.
        let held = Point2::new(home.x + 4.0 * side, home.y);
        park(&mut t, held, 2 * PARKED_FRAMES);
        t.learn_parked();
        assert_eq!(t.markers[0].misses, 0);
        assert!(all_tracked(&t, 0));
        Ok(())
    }

    /// One step of the markers' learnt motion, pixels.
    const STEP_PX: f64 = 8.0;

    /// Four look-alike targets in a row, 40 px apart (white squares with a black dot, gray
    /// model; red squares, hue model, when `colour`), seen moving alike ([`STEP_PX`] a
    /// frame) if `learned`.
    fn row_of_four(learned: bool, colour: bool) -> Result<Tracker> {
        let centres = [20u32, 60, 100, 140];
        let frame = RgbImage::from_fn(192, 64, |x, y| {
            let near = |r: u32| {
                centres
                    .iter()
                    .any(|&c| x.abs_diff(c) <= r && y.abs_diff(30) <= r)
            };
            match (near(1), near(4), colour) {
                (_, true, true) => image::Rgb([215, 25, 30]),
                (true, _, false) => image::Rgb([20, 20, 20]),
                (false, true, false) => image::Rgb([235, 235, 235]),
                _ => image::Rgb([100, 110, 95]),
            }
        });
        let inits: Vec<MarkerInit> = centres
            .iter()
            .zip(["A", "B", "C", "D"])
            .map(|(&c, id)| MarkerInit {
                id: id.into(),
                window: PixelRect::new(c as i32 - 5, 25, 11, 11),
            })
            .collect();
        let config = if colour {
            TrackerConfig::default()
        } else {
            TrackerConfig::for_model(AppearanceModel::Gray { bins: 32 })
        };
        let mut t = Tracker::new(config, &frame, None, &inits)?;
        let step = Vector2::new(STEP_PX, 0.0);
        for c in t.coherence.iter_mut().filter(|_| learned) {
            for _ in 0..10 {
                c.learn(step, step);
            }
        }
        Ok(t)
    }

    /// Each marker found moved by its displacement along x; C (the third) with `status`,
    /// the others tracked.
    fn moved_by(t: &Tracker, moves: [f64; 4], status: TrackStatus) -> Vec<Option<Found>> {
        t.markers
            .iter()
            .zip(moves)
            .enumerate()
            .map(|(k, (m, dx))| {
                let c = m.last_center + Vector2::new(dx, 0.0);
                let window = PixelRect::centered_at(c, 11, 11);
                let q = Measured {
                    center: c,
                    window,
                    holds: window,
                    confidence: 0.95,
                    moments: None,
                    cut: false,
                    split: false,
                    misfit: 0.0,
                    spread: None,
                };
                let status = if k == 2 { status } else { TrackStatus::Tracked };
                Some((q, status, None))
            })
            .collect()
    }

    /// Where the others say C went, if C's move is flagged.
    fn c_flagged(t: &Tracker, moves: [f64; 4], status: TrackStatus) -> Option<Vector2<f64>> {
        let results = moved_by(t, moves, status);
        t.incoherent(&results)
            .into_iter()
            .find(|f| f.0 == 2)
            .map(|f| f.1)
    }

    #[test]
    fn a_jump_the_markers_it_moves_with_did_not_make_is_looked_at_again() -> Result<()> {
        use TrackStatus::{Recovered, Tracked};
        let t = row_of_four(true, false)?;
        // C jumps back onto B's target while A, B and D move on together (a row of targets
        // whose prediction for C lands on B's): looked for with them, whether the quick pass
        // or detection found it.
        let jump = [30.0, 31.0, -10.0, 29.0];
        assert_eq!(t.incoherent(&moved_by(&t, jump, Tracked)).len(), 1);
        let went = c_flagged(&t, jump, Tracked).expect("flagged");
        assert!((went.x - 30.0).abs() <= 1.0, "{went:?}");
        assert!(c_flagged(&t, jump, Recovered).is_some());
        // No jump (half a window at most: mean-shift's reach), or with the row within a
        // window of it: not flagged.
        assert!(c_flagged(&t, [30.0, 31.0, 5.0, 29.0], Tracked).is_none());
        assert!(c_flagged(&t, [30.0, 31.0, 21.0, 29.0], Tracked).is_none());
        // One of the others fooled the same way (B jumped back with C): the majority still
        // says otherwise. Two of three with C: no majority against it.
        assert!(c_flagged(&t, [30.0, -12.0, -10.0, 29.0], Tracked).is_some());
        assert!(c_flagged(&t, [30.0, -12.0, -10.0, -9.0], Tracked).is_none());
        // A rig that turns: C has moved twice as far as the others. With them at 15 px, C at
        // 30 px is with them, and a jump back is not.
        let mut turning = row_of_four(false, false)?;
        let step = Vector2::new(STEP_PX, 0.0);
        for j in [0, 1, 3] {
            for _ in 0..10 {
                turning.coherence[2 * 4 + j].learn(2.0 * step, step);
            }
        }
        assert!(c_flagged(&turning, [15.0, 15.0, 30.0, 15.0], Tracked).is_none());
        let went = c_flagged(&turning, [15.0, 15.0, -10.0, 15.0], Tracked).expect("flagged");
        assert!((went.x - 30.0).abs() <= 1.0, "{went:?}");
        // Markers never seen moving are not witnesses; colour markers are told apart by
        // colour and swing lines, not by this rule.
        assert!(c_flagged(&row_of_four(false, false)?, jump, Tracked).is_none());
        assert!(c_flagged(&row_of_four(true, true)?, jump, Tracked).is_none());
        Ok(())
    }

    #[test]
    fn surroundings_that_correlate_far_below_their_usual_level_decide_less() -> Result<()> {
        let mut t = row_of_four(false, false)?;
        let m = &mut t.markers[2];
        assert!(m.context.is_some(), "a gray target has surroundings");
        // Usually 0.98 with a spread under the floor (a still rig, sharp frames).
        m.context_level = 0.98;
        m.context_var = 1e-4;
        let at = m.filter.position;
        let candidate = |dx: f64, confidence: f64, context: f64| {
            let window = PixelRect::centered_at(at + Vector2::new(dx, 0.0), 11, 11);
            let measured = Measured {
                center: window.center(),
                window,
                holds: window,
                confidence,
                moments: None,
                cut: false,
                split: false,
                misfit: 0.0,
                spread: None,
            };
            (measured, Some(context))
        };
        let wide = 400.0;
        let costs = |own: f64, other: f64| {
            let scored = m.score(
                &[candidate(-3.0, 0.97, own), candidate(3.0, 0.95, other)],
                wide,
                false,
            );
            (scored[0].cost, scored[1].cost)
        };
        // Two places as far from the prediction, the other a little less like the marker
        // (0.95 against 0.97). A blurred frame: both surroundings far below 0.98, the
        // other's 0.11 better; the place that looks more like the marker wins.
        let (own, other) = costs(0.63, 0.74);
        assert!(own < other, "{own} against {other}");
        // A sharp frame, the same difference near the usual level: the surroundings decide.
        let (own, other) = costs(0.87, 0.97);
        assert!(own > other, "{own} against {other}");
        // The spread's factor: (1 - 0.74^2) / (1 - 0.98^2), and never below 1.
        assert!((correlation_spread(0.98, 0.74) - 0.4524 / 0.0396).abs() < 1e-9);
        assert_eq!(correlation_spread(0.9, 0.95), 1.0);
        assert!((correlation_spread(1.0, 0.9) - 0.19 / CORRELATION_SPREAD_FLOOR).abs() < 1e-9);
        Ok(())
    }

    #[test]
    fn a_gray_target_less_alike_than_its_template_usually_is_not_taken_unopposed() -> Result<()> {
        // A template's correlation with its own target varies by hundredths (real targets
        // at a release: 0.97 and up); a neighbour's look-alike target correlates 0.75–0.9.
        let mut gray = row_of_four(false, false)?;
        let mut colour = row_of_four(false, true)?;
        for m in gray.markers.iter_mut().chain(colour.markers.iter_mut()) {
            m.confidence_mean = 0.99;
            m.confidence_var = 1e-5;
        }
        let (target, red) = (&gray.markers[2], &colour.markers[2]);
        assert!(target.template.is_some() && red.template.is_none());
        assert!(target.typical(0.96));
        assert!(
            !target.typical(0.9),
            "a look-alike target goes to detection"
        );
        // A colour histogram's likeness varies far more (blur, light): 0.8 is still usual.
        assert!(red.typical(0.8));
        Ok(())
    }

    #[test]
    fn a_lone_witness_overrules_only_a_jump_found_on_a_weaker_likeness() -> Result<()> {
        use TrackStatus::Tracked;
        // Only C and D have been seen moving together (the rows above and below too little).
        let mut t = row_of_four(false, false)?;
        let step = Vector2::new(STEP_PX, 0.0);
        for (a, b) in [(2, 3), (3, 2)] {
            for _ in 0..10 {
                t.coherence[a * 4 + b].learn(step, step);
            }
        }
        let found = |moves: [f64; 4], c_confidence: f64| {
            let mut r = moved_by(&t, moves, Tracked);
            if let Some(c) = r[2].as_mut() {
                c.0.confidence = c_confidence;
            }
            r
        };
        // C jumps back while D moves on, and C's place looks less like C than D's like D
        // (0.85 against 0.95): C is looked for where D says; D is not, on C's word.
        let jump = [0.0, 0.0, -10.0, 29.0];
        let flagged = t.incoherent(&found(jump, 0.85));
        assert_eq!(flagged.len(), 1, "{flagged:?}");
        assert_eq!(flagged[0].0, 2);
        assert!((flagged[0].1.x - 29.0).abs() <= 1.0, "{flagged:?}");
        // As sure as D (within the margin): one against one, nobody is overruled.
        assert!(t.incoherent(&found(jump, 0.93)).is_empty());
        // A disagreement under two windows (15 px, windows of 11) is not enough alone.
        assert!(
            t.incoherent(&found([0.0, 0.0, 14.0, 29.0], 0.85))
                .is_empty()
        );
        Ok(())
    }

    #[test]
    fn a_witness_may_be_off_by_half_of_what_it_gives() -> Result<()> {
        use TrackStatus::Tracked;
        let t = row_of_four(true, false)?;
        // The others say 60 px, C moved 35: 25 px apart, more than a window (11 px) but
        // within half of 60 (a gain learnt over the first frames of a release is rough).
        assert!(c_flagged(&t, [60.0, 60.0, 35.0, 60.0], Tracked).is_none());
        // 70 px apart (a jump back onto the neighbour's target) is flagged.
        assert!(c_flagged(&t, [60.0, 60.0, -10.0, 60.0], Tracked).is_some());
        Ok(())
    }

    #[test]
    fn witnesses_found_on_a_weaker_likeness_do_not_testify() -> Result<()> {
        use TrackStatus::Tracked;
        let t = row_of_four(true, false)?;
        // C (found at 0.99) moved on while A, B and D jumped back together, each found on
        // a weaker likeness (0.9): they cannot overrule it. Found as surely, they can.
        let found = |others: f64| {
            let mut r = moved_by(&t, [-10.0, -11.0, 30.0, -9.0], Tracked);
            for (k, f) in r.iter_mut().enumerate() {
                if let Some(f) = f.as_mut() {
                    f.0.confidence = if k == 2 { 0.99 } else { others };
                }
            }
            r
        };
        let c_flagged = |others: f64| t.incoherent(&found(others)).iter().any(|f| f.0 == 2);
        assert!(!c_flagged(0.9));
        assert!(c_flagged(0.98));
        Ok(())
    }

    #[test]
    fn a_target_that_moved_against_its_rig_before_any_gain_is_known_is_looked_at_again()
    -> Result<()> {
        use TrackStatus::Tracked;
        // C has been seen moving the same way as the others, but eight times as far: no
        // gain yet (the first frame of a release, a row far from the pivot).
        let mut t = row_of_four(false, false)?;
        for j in [0, 1, 3] {
            for _ in 0..10 {
                t.coherence[2 * 4 + j].learn(Vector2::new(8.0, 0.0), Vector2::new(1.5, 0.0));
                t.coherence[j * 4 + 2].learn(Vector2::new(1.5, 0.0), Vector2::new(8.0, 0.0));
            }
        }
        assert!(t.coherence[2 * 4].gain(11.0).is_none());
        let found = |c_move: f64, c_confidence: f64| {
            let mut r = moved_by(&t, [20.0, 20.0, c_move, 20.0], Tracked);
            for (k, f) in r.iter_mut().enumerate() {
                if let Some(f) = f.as_mut() {
                    f.0.confidence = if k == 2 { c_confidence } else { 0.99 };
                }
            }
            r
        };
        // The others jumped 20 px to the right, C 10 px to the left on a weaker likeness:
        // looked for again to the right.
        let against = t.against_the_rig(&found(-10.0, 0.85));
        assert_eq!(against.len(), 1, "{against:?}");
        assert_eq!(against[0].0, 2);
        assert!((against[0].1.x - 1.0).abs() < 1e-9, "{against:?}");
        // With them, by a little against them (mean-shift's noise), or as sure: not.
        assert!(t.against_the_rig(&found(10.0, 0.85)).is_empty());
        assert!(t.against_the_rig(&found(-2.0, 0.85)).is_empty());
        assert!(t.against_the_rig(&found(-10.0, 0.97)).is_empty());
        // Once a gain is known, [`Tracker::incoherent`] judges instead.
        let learned = row_of_four(true, false)?;
        let mut r = moved_by(&learned, [20.0, 20.0, -10.0, 20.0], Tracked);
        if let Some(c) = r[2].as_mut() {
            c.0.confidence = 0.85;
        }
        assert!(learned.against_the_rig(&r).is_empty());
        Ok(())
    }

    /// A gray 192x64 frame with a red 9x9 marker centred at `(marker_x, 30)` and a paler,
    /// larger reddish disc (radius 8) centred at `(60, 30)`: a look-alike the marker's
    /// weights hold only weakly.
    fn marker_beside_a_pale_disc(marker_x: u32) -> RgbImage {
        RgbImage::from_fn(192, 64, |x, y| {
            let (dx, dy) = (f64::from(x) - 60.0, f64::from(y) - 30.0);
            if y.abs_diff(30) <= 4 && x.abs_diff(marker_x) <= 4 {
                image::Rgb([215, 25, 30])
            } else if dx * dx + dy * dy <= 64.0 {
                image::Rgb([170, 95, 90])
            } else {
                image::Rgb([100, 110, 95])
            }
        })
    }

    /// Where marker A is found in a frame with the marker at `(100, 30)`, its track having
    /// followed the pale disc at `(60, 30)` on weak measurements for three frames, standing
    /// still (`still`) or not.
    fn found_after_weak_run(still: bool) -> Result<Option<Point2<f64>>> {
        let mut t = Tracker::new(
            TrackerConfig::default(),
            &marker_beside_a_pale_disc(20),
            None,
            &[MarkerInit {
                id: "A".into(),
                window: PixelRect::new(15, 25, 11, 11),
            }],
        )?;
        let disc = Point2::new(60.0, 30.0);
        let m = &mut t.markers[0];
        m.filter.position = disc;
        m.filter.velocity = Vector2::zeros();
        m.last_center = disc;
        m.last_status = TrackStatus::Predicted;
        m.confidence_mean = 0.6;
        m.weak_run = WEAK_STILL_FRAMES;
        m.weak_place = Some((disc, if still { WEAK_STILL_FRAMES } else { 1 }));
        // Away from its home (where it started, 40 px off): held, when still.
        assert_eq!(m.held_by_still_weak(), still);
        let home = m.home;
        m.home = disc;
        assert!(
            !m.held_by_still_weak(),
            "at its home a marker may rest half hidden"
        );
        m.home = home;
        t.update(&marker_beside_a_pale_disc(100), None)?;
        let o = &t.tracks()[0].observations[1];
        Ok(o.center.filter(|_| o.status.found()))
    }

    #[test]
    fn a_track_standing_still_on_weak_measurements_lets_go_for_its_marker() -> Result<()> {
        // Held on the disc for three frames: the marker, 40 px away and sure, is taken.
        let found = found_after_weak_run(true)?;
        assert!(
            found.is_some_and(|c| (c - Point2::new(100.0, 30.0)).norm() < 1.5),
            "{found:?}"
        );
        // Weak measurements that moved (a blurred marker on its way) keep their hold.
        let found = found_after_weak_run(false)?;
        assert!(found.is_none(), "{found:?}");
        Ok(())
    }
}
