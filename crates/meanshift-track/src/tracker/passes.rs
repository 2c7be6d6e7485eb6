//! The two passes of a frame: mean-shift from each prediction (the quick pass), then
//! detection and joint assignment for every marker the quick pass did not settle.

use super::*;

impl Tracker {
    /// Marker `i`'s quick pass: its candidates near the prediction (the gray template's
    /// matches, or the blobs of its weights), scored together; the best, and the places of
    /// the others. Plain mean-shift's mode without recovery, or as the fallback of a
    /// colour model when no blob fits (at half its confidence). A colour marker's best blob
    /// that the region about the prediction cut (a marker turning at the end of a fast
    /// swing, which the prediction overshot) is weighed again in a region about it, and
    /// measured whole there when the second region holds it whole ([`holds_whole`]).
    ///
    /// A settled colour marker ([`Tracker::settled`]) is weighed first in a narrow region
    /// (a quarter of the full one's pixels); its best stands only when the region holds no
    /// other candidate and the best is whole, near the prediction and as confident as the
    /// marker usually is ([`Tracker::settles`]), else the full region is weighed. The full
    /// region is weighed again at least every [`NARROW_RECHECK_FRAMES`] frames, so that
    /// look-alikes near the marker are seen and remembered as before (a narrow region
    /// every frame left one unlearnt and lost a marker for five frames at its release on
    /// the third generator's seed 2). The same tracks on the stress sequences and on all
    /// third-generator ones but one (hs model, seed 109, which gained), for 13 % fewer
    /// instructions on the Kinect-style condition (`docs/benchmarks.md`).
    pub(super) fn quick_pass(
        &mut self,
        frame: &RgbImage,
        depth: Option<&DepthView<'_>>,
        i: usize,
        predictions: &[Point2<f64>],
    ) -> QuickFound {
        let colour = self.markers[i].template.is_none() && self.config.recovery;
        let pred = predictions[i];
        let narrow = colour && self.settled(i, pred);
        let mut first = self.quick_about(frame, depth, i, predictions, pred, narrow);
        let stands = |t: &Self, f: &QuickFound| {
            f.1.is_empty() && f.0.is_some_and(|b| t.settles(i, pred, &b.measured))
        };
        let stood = narrow && stands(self, &first);
        if narrow && !stood {
            first = self.quick_about(frame, depth, i, predictions, pred, false);
        }
        if colour && !stood {
            // A full region with nothing else in it: the next frames may weigh a narrow one.
            let now = self.frames();
            self.markers[i].clear_at = first.1.is_empty().then_some(now);
        }
        if let (true, Some(cut)) = (colour, first.0.filter(|b| b.measured.cut)) {
            let again = self.quick_about(frame, depth, i, predictions, cut.measured.center, false);
            if again
                .0
                .is_some_and(|w| holds_whole(&w.measured, &cut.measured))
            {
                return again;
            }
        }
        first
    }

    /// Whether marker `i` is settled enough for a narrow quick pass: found on the last
    /// frame without a miss or a weak measurement, its prediction certain to a small share
    /// of its window, no marker of its look and no look-alike it knows near, and its full
    /// region found holding nothing else a few frames ago ([`NARROW_RECHECK_FRAMES`]).
    fn settled(&self, i: usize, pred: Point2<f64>) -> bool {
        let m = &self.markers[i];
        let side = window_px(m);
        m.clear_at
            .is_some_and(|f| self.frames() < f + NARROW_RECHECK_FRAMES)
            && m.misses == 0
            && m.weak_run == 0
            && m.last_status == TrackStatus::Tracked
            && (GATE_CHI2 * m.gate_var).sqrt() <= NARROW_GATE_WINDOWS * side
            && !crowded(&self.markers, i)
            && m.distractors
                .iter()
                .all(|d| (d.at - pred).norm() > NARROW_CLEAR_WINDOWS * side)
    }

    /// Whether the narrow quick pass's best of marker `i` stands: whole in the region, near
    /// the prediction, and as confident as the marker usually is.
    fn settles(&self, i: usize, pred: Point2<f64>, best: &Measured) -> bool {
        let m = &self.markers[i];
        !best.cut
            && (best.center - pred).norm() <= NARROW_REACH_WINDOWS * window_px(m)
            && best.confidence >= self.config.min_confidence
            && m.typical(best.confidence)
    }

    /// [`Tracker::quick_pass`] over the region about `about` (the prediction, or a blob the
    /// region about it cut).
    fn quick_about(
        &mut self,
        frame: &RgbImage,
        depth: Option<&DepthView<'_>>,
        i: usize,
        predictions: &[Point2<f64>],
        about: Point2<f64>,
        narrow: bool,
    ) -> (Option<Scored>, Vec<(Point2<f64>, PixelRect)>) {
        let frame_side = f64::from(self.width.max(self.height));
        let m = &self.markers[i];
        let pred = predictions[i];
        let side = window_px(m);
        let wide = m.gate_var + manoeuvre_var(&self.config, side, m.searching(), frame_side);
        let mut found: Vec<Measured>;
        let mut fallback = None;
        if let (Some(t), true) = (&m.template, self.config.recovery) {
            let radius = (GATE_CHI2 * m.gate_var)
                .sqrt()
                .clamp(0.25 * side, 1.5 * side);
            found = template_candidates(t, m, frame, pred, radius, 4, &mut self.patch);
        } else {
            let region = quick_region(m, about, narrow);
            let masks = m.static_masks(region, pred);
            fill(
                &mut self.region,
                &self.config,
                m,
                frame,
                self.previous.as_ref(),
                depth,
                region,
                &masks,
                &m.paler_boxes(region, &masks),
                false,
            );
            let mode = self.region.locate(
                &m.model,
                &self.config.criteria,
                m.reference.mass,
                about,
                m.size,
            );
            let plain_mode = plain(&self.region, mode);
            if !self.config.recovery {
                let scored = Scored {
                    measured: plain_mode,
                    context: None,
                    cost: 0.0,
                };
                return (Some(scored), Vec::new());
            }
            let (others, others_pixels) = sharing_predictions(&self.markers, i, predictions);
            let look_alikes = self.look_alikes_beside(i, pred);
            let near = Near {
                own: Some(pred),
                others: &others,
                others_pixels: &others_pixels,
                look_alikes: &look_alikes,
                partners: &partners_of(&self.markers, i),
                contested: &[],
            };
            found = candidates_in(&mut self.region, &mut self.labeler, m, &near);
            let image = (self.width, self.height);
            found
                .iter_mut()
                .for_each(|c| c.cut = cut_by(c.holds, region, image));
            fallback = Some(Measured {
                confidence: plain_mode.confidence * 0.5,
                ..plain_mode
            });
        }
        // Surroundings tell candidates apart only when there is a choice; the chosen one's
        // are measured below in any case.
        let ambiguous = found.len() > 1 && m.context_informative();
        let with_context: Vec<(Measured, Option<f64>)> = found
            .into_iter()
            .map(|c| {
                let context = ambiguous
                    .then(|| {
                        m.context
                            .as_ref()
                            .map(|t| t.ncc_near(frame, c.center, &mut self.patch))
                    })
                    .flatten();
                (c, context)
            })
            .collect();
        let mut scored = m.score(&with_context, wide, crowded(&self.markers, i));
        scored.sort_by(|a, b| a.cost.total_cmp(&b.cost));
        let others = scored
            .iter()
            .skip(1)
            .map(|c| (c.measured.center, c.measured.holds))
            .collect();
        let mut best = scored.into_iter().next().or_else(|| {
            fallback.map(|f| Scored {
                measured: f,
                context: None,
                cost: f64::INFINITY,
            })
        });
        if let Some(b) = best.as_mut()
            && b.context.is_none()
        {
            b.context = m
                .context
                .as_ref()
                .map(|t| t.ncc_near(frame, b.measured.center, &mut self.patch));
        }
        (best, others)
    }

    /// Marker `i`'s static look-alikes that a blob about `at` may hold beside it (see
    /// [`candidates_in`]); none where a marker of the same look is near (two markers of one
    /// look are split by their predictions alone).
    fn look_alikes_beside(&self, i: usize, at: Point2<f64>) -> Vec<Point2<f64>> {
        if crowded(&self.markers, i) {
            Vec::new()
        } else {
            self.markers[i].look_alikes_away(at)
        }
    }

    /// Open the gates of `undecided` markers, find candidates in them (other markers'
    /// places masked), and assign candidates (with each marker's quick-pass measurement) to
    /// markers jointly. Per undecided marker: its measurement and context correlation, or
    /// `None`. Nothing is learnt yet: see [`Tracker::learn_detection`].
    pub(super) fn detect_and_assign(
        &mut self,
        frame: &RgbImage,
        depth: Option<&DepthView<'_>>,
        undecided: &[usize],
        claimed: &[Claim],
        quick: &[Option<Scored>],
        confined: &[Confined],
    ) -> Detection {
        let mut candidates: Vec<Candidate> = Vec::new();
        let mut seen: Vec<Vec<(Point2<f64>, PixelRect)>> = Vec::with_capacity(undecided.len());
        for &i in undecided {
            let (mut scored, blobs) = self.detect(frame, depth, i, claimed, quick[i]);
            scored.retain(|c| {
                confined
                    .iter()
                    .all(|f| f.marker != i || f.holds(c.measured.center))
            });
            candidates.extend(scored);
            seen.push(blobs);
        }
        let chosen = self.assign_places(&candidates, undecided, claimed, quick);
        Detection { chosen, seen }
    }

    /// Detection again after [`Tracker::flags`]: each flagged marker is moved to where its
    /// witnesses say it went and looked for again, only at places nearer to that by a
    /// window than the one it took (or, told only a direction, only along it; none there:
    /// not found in this frame), together with the undecided markers of its look within
    /// [`NEIGHBOUR_RADIUS_WINDOWS`] of it (one of them may have lacked the place it took) and those detection did not find; the other
    /// markers' detections stand and hold their places. `results` and `claimed` are
    /// updated; the markers detection decided and its answer for them are returned, for
    /// [`Tracker::learn_detection`].
    pub(super) fn redetect(
        &mut self,
        frame: &RgbImage,
        depth: Option<&DepthView<'_>>,
        again: Again<'_>,
        results: &mut [Option<Found>],
        claimed: &mut Vec<Claim>,
    ) -> (Vec<usize>, Detection) {
        let Again {
            flagged,
            undecided,
            first,
            quick,
        } = again;
        let mut confined = Vec::with_capacity(flagged.len());
        for f in flagged {
            let i = f.marker;
            let m = &mut self.markers[i];
            let taken = results[i].take();
            match f.went {
                Went::By(moved) => {
                    let answer = m.last_center + moved;
                    m.filter.position = answer;
                    // Only places clearly nearer to the witnesses' answer than the one it
                    // took: if none is, the target is not found in this frame rather than
                    // found there again.
                    if let Some((taken, _, _)) = taken {
                        confined.push(Confined {
                            marker: i,
                            center: answer,
                            radius_px: (taken.center - answer).norm() - window_px(m),
                            along: None,
                        });
                    }
                }
                // Only places it reaches by moving with the rig, from its prediction.
                Went::Along(direction) => confined.push(Confined {
                    marker: i,
                    center: m.last_center,
                    radius_px: f64::INFINITY,
                    along: Some(direction),
                }),
            }
        }
        claimed.retain(|c| flagged.iter().all(|f| f.marker != c.0));
        let near_flagged = |u: usize| {
            flagged.iter().map(|f| f.marker).any(|f| {
                let (a, b) = (&self.markers[u], &self.markers[f]);
                same_look(a, b)
                    && (a.last_center - b.last_center).norm()
                        <= NEIGHBOUR_RADIUS_WINDOWS * window_px(b)
            })
        };
        let mut redo: Vec<usize> = flagged.iter().map(|f| f.marker).collect();
        let others: Vec<usize> = undecided
            .iter()
            .copied()
            .filter(|&u| !redo.contains(&u) && (results[u].is_none() || near_flagged(u)))
            .collect();
        redo.extend(others);
        // The rest keep what detection gave them, and hold those places.
        let mut kept = Vec::new();
        let mut chosen = Vec::new();
        let mut seen = Vec::new();
        let mut holds = claimed.clone();
        for ((u, pick), blobs) in undecided.into_iter().zip(first.chosen).zip(first.seen) {
            if redo.contains(&u) {
                continue;
            }
            if let Some((q, _)) = pick {
                holds.push((u, q.holds, q.center));
            }
            kept.push(u);
            chosen.push(pick);
            seen.push(blobs);
        }
        let second = self.detect_and_assign(frame, depth, &redo, &holds, quick, &confined);
        second.record_in(&redo, results);
        kept.extend(redo);
        chosen.extend(second.chosen);
        seen.extend(second.seen);
        (kept, Detection { chosen, seen })
    }

    /// What detection of the `undecided` markers teaches: a marker found far outside its
    /// normal gate has manoeuvred (the filter takes the manoeuvre, so the measurement sets
    /// the new velocity), and what it saw in its gate and did not take is a look-alike.
    pub(super) fn learn_detection(
        &mut self,
        undecided: &[usize],
        claimed: &[Claim],
        detection: Detection,
    ) {
        let frame_side = f64::from(self.width.max(self.height));
        for (&i, pick) in undecided.iter().zip(&detection.chosen) {
            let m = &mut self.markers[i];
            if let Some((q, _)) = pick
                && (q.center - m.filter.position).norm_squared() > GATE_CHI2 * m.gate_var
            {
                let side = window_px(m);
                let sigma = manoeuvre_var(&self.config, side, m.misses, frame_side).sqrt();
                m.filter.manoeuvre(sigma);
            }
        }
        self.learn_gate_look_alikes(undecided, claimed, &detection.chosen, detection.seen);
    }

    /// Marker `i`'s search gate this frame: the miss may be a manoeuvre (a release), so the
    /// search opens to the search radius, and wider while the marker stays unseen, up to the
    /// whole frame. The filter takes the manoeuvre only if a candidate is taken.
    pub(super) fn gate(&self, i: usize) -> Gate {
        let m = &self.markers[i];
        self.gate_of(m, &m.filter, m.gate_var)
    }

    /// The search gate of marker `m` predicted to `filter`, whose normal gate has variance
    /// `gate_var` (see [`Tracker::gate`]).
    fn gate_of(&self, m: &MarkerState, filter: &Kalman, gate_var: f64) -> Gate {
        let (width, height) = (self.width, self.height);
        let frame_side = f64::from(width.max(height));
        let side = window_px(m);
        let wide_var = gate_var + manoeuvre_var(&self.config, side, m.searching(), frame_side);
        let center = clamp_into(filter.position, width, height);
        // A marker that has left the frame comes back across the border near where it
        // left: its gate is the normal one around the border point, widened by a window
        // per missed frame, not the whole frame (where it would take whatever looks like
        // it on the far side).
        // (Only a marker last seen near the border has left: one predicted out of the
        // frame from the middle of it has a wrong velocity, and is searched everywhere.)
        let size = (width, height);
        let exit_edge = Edge::nearest(m.last_center, size);
        let border_gap = exit_edge.depth(m.last_center, size);
        let outside = (filter.position - center).norm() > 0.5 * side
            && border_gap < BORDER_WINDOWS * side + filter.velocity.norm();
        let border_px = (GATE_CHI2 * gate_var).sqrt() + (m.misses as f64 + 1.0) * side;
        let radius_px = if outside {
            (GATE_CHI2 * wide_var).sqrt().min(border_px)
        } else {
            (GATE_CHI2 * wide_var).sqrt().min(2.0 * frame_side)
        };
        // A marker missing since it was last found at a border, and believed still beyond
        // it or near it, comes back across that border: where it is first seen again lies
        // within a frame or two of its speed from it, not across the frame (a marker pulled
        // out of the top of the frame was taken again on a look-alike 100-250 px below the
        // edge, on the third generator's tuning seeds 6, 8, 12 and 22, and on our
        // generator's combined seed 1005 a marker gone out at the right took another's
        // place 200 px inside). Once the prediction is deeper than that (its swing or its
        // hold brings it back), the gate is as for any marker. So is it for a marker last
        // found again far from where it coasted (one seen again at the border after it was
        // out of the frame came in across it, and swings on inside: the third generator's
        // seed 26 lost one so for 5 frames while it passed 20-100 px below the border).
        let entry_px = BORDER_WINDOWS * side
            + ENTRY_SPEED_FRAMES * m.exit_speed_px.max(ENTRY_RELEASE_WINDOWS * side);
        let entry = (m.misses > 0
            && !m.restarted
            && border_gap < BORDER_WINDOWS * side + m.exit_speed_px
            && exit_edge.depth(filter.position, size) <= entry_px)
            .then_some((exit_edge, entry_px));
        Gate {
            wide_var,
            center,
            outside,
            radius_px,
            entry,
            size,
        }
    }

    /// Where the next frame's passes may weigh colour marker pixels (each marker's quick
    /// region about its prediction and its detection region about its gate, from the
    /// filters as the next frame will predict them): the parts of this frame to keep as
    /// that frame's streak background.
    pub(super) fn next_regions(&self) -> Vec<PixelRect> {
        let size = (self.width, self.height);
        let mut regions = Vec::with_capacity(2 * self.markers.len());
        let frame_index = self.frames() as u64;
        for m in self.markers.iter().filter(|m| m.template.is_none()) {
            let filter = m.predicted(&self.config, size, frame_index);
            let gate_var = filter.innovation_var(MEASUREMENT_PX);
            let pred = clamp_into(filter.position, self.width, self.height);
            regions.push(quick_region(m, pred, false));
            regions.push(detection_region(m, &self.gate_of(m, &filter, gate_var)));
        }
        regions
    }

    /// Marker `i`'s scored candidates in its gate (the quick pass's own measurement among
    /// them: a marker half behind a twig), and every place it saw there.
    fn detect(
        &mut self,
        frame: &RgbImage,
        depth: Option<&DepthView<'_>>,
        i: usize,
        claimed: &[Claim],
        quick: Option<Scored>,
    ) -> (Vec<Candidate>, Vec<(Point2<f64>, PixelRect)>) {
        let gate = self.gate(i);
        let frame_index = self.frames();
        let mut cluttered = false;
        let mut found: Vec<Measured> = quick.iter().map(|q| q.measured).collect();
        let m = &self.markers[i];
        if let Some(t) = &m.template {
            found.extend(template_candidates(
                t,
                m,
                frame,
                gate.center,
                gate.radius_px,
                MAX_CANDIDATES,
                &mut self.patch,
            ));
        } else {
            let region = detection_region(m, &gate);
            let mut masks: Vec<PixelRect> = if self.config.exclusive {
                claimed.iter().map(|c| c.1).collect()
            } else {
                Vec::new()
            };
            masks.extend(m.static_masks(region, gate.center));
            // The moments of the adaptive window read a border beyond what a sparse fill
            // weighs; a gate found cluttered lately is weighed whole.
            let sparse = self.config.window == WindowMode::Fixed && frame_index >= m.dense_until;
            fill(
                &mut self.region,
                &self.config,
                m,
                frame,
                self.previous.as_ref(),
                depth,
                region,
                &masks,
                &m.paler_boxes(region, &masks),
                sparse,
            );
            cluttered = self.region.cluttered;
            let all: Vec<Point2<f64>> = self.markers.iter().map(|m| m.filter.position).collect();
            let (others, others_pixels) = sharing_predictions(&self.markers, i, &all);
            let contested = self.contested(i, claimed);
            let look_alikes = self.look_alikes_beside(i, gate.center);
            let near = Near {
                own: Some(gate.center),
                others: &others,
                others_pixels: &others_pixels,
                look_alikes: &look_alikes,
                partners: &partners_of(&self.markers, i),
                contested: &contested,
            };
            found.extend(
                candidates_in(&mut self.region, &mut self.labeler, m, &near)
                    .into_iter()
                    .take(MAX_CANDIDATES),
            );
        }
        let whole = quick.and_then(|q| whole_of_cut(m, &q.measured, &found[1..]));
        found.retain(|c| gate.admits(c.center));
        let seen: Vec<(Point2<f64>, PixelRect)> =
            found.iter().map(|c| (c.center, c.holds)).collect();
        let mut with_context = Vec::with_capacity(found.len());
        for c in found {
            if c.confidence < self.config.min_confidence
                || (self.config.exclusive && taken(&self.markers, i, c.center, claimed))
            {
                continue;
            }
            let context = m
                .context
                .as_ref()
                .filter(|_| m.context_informative())
                .map(|t| t.ncc_near(frame, c.center, &mut self.patch));
            with_context.push((c, context));
        }
        let previous = self.previous.as_ref();
        let scored = m
            .score(&with_context, gate.wide_var, crowded(&self.markers, i))
            .into_iter()
            .map(|mut s| {
                if let Some(prev) = previous
                    && m.misses == 0
                    && m.template.is_none()
                    && (s.measured.center - m.last_center).norm() > window_px(m)
                    && !streak_along_motion(m, s.measured.holds)
                    && changed_share(frame, prev, s.measured.holds) < STATIC_SHARE
                {
                    s.cost += STATIC_JUMP_COST;
                }
                Candidate {
                    marker: i,
                    measured: seen_whole(s.measured, whole),
                    cost: s.cost,
                    context: s.context,
                }
            })
            .collect();
        if cluttered {
            self.markers[i].dense_until = frame_index + CLUTTER_HOLD_FRAMES;
        }
        (scored, seen)
    }

    /// The predictions of the markers that detection decides together with marker `i`:
    /// the others found in the last frame that no quick pass claimed (the same points as
    /// [`sharing_predictions`] gives, for [`Near::contested`]).
    fn contested(&self, i: usize, claimed: &[Claim]) -> Vec<Point2<f64>> {
        self.markers
            .iter()
            .enumerate()
            .filter(|&(j, o)| j != i && o.misses == 0 && claimed.iter().all(|c| c.0 != j))
            .map(|(_, o)| o.filter.position)
            .collect()
    }

    /// The joint, exclusive assignment of `candidates` to the `undecided` markers. Columns
    /// are places, so that markers of one colour compete for the same blob; the markers
    /// already decided (`claimed`) anchor their neighbours.
    fn assign_places(
        &self,
        candidates: &[Candidate],
        undecided: &[usize],
        claimed: &[Claim],
        quick: &[Option<Scored>],
    ) -> Vec<Option<(Measured, Option<f64>)>> {
        let mut places: Vec<(Point2<f64>, f64, PixelRect)> = Vec::new();
        let mut column = Vec::with_capacity(candidates.len());
        for c in candidates {
            let side = window_px(&self.markers[c.marker]);
            let here = (c.measured.center, side, c.measured.holds);
            let same = places.iter().position(|place| one_place(*place, here));
            column.push(same.unwrap_or_else(|| {
                places.push((c.measured.center, side, c.measured.holds));
                places.len() - 1
            }));
        }
        let cols = places.len();
        let mut cost = vec![f64::INFINITY; undecided.len() * cols];
        for (c, &j) in candidates.iter().zip(&column) {
            if let Some(r) = undecided.iter().position(|&i| i == c.marker) {
                // Gray targets in rows swing across each other's places and are guided by
                // their neighbours instead, which these costs would fight.
                let extra = if self.markers[c.marker].template.is_none() {
                    self.colour_cost(c.marker, places[j].0, undecided, quick)
                } else {
                    0.0
                };
                let slot = &mut cost[r * cols + j];
                *slot = slot.min(c.cost + extra);
            }
        }
        self.price_spread(&mut cost, cols, undecided);
        let anchors: Vec<Anchor> = claimed
            .iter()
            .map(|&(j, _, c)| {
                let last = self.markers[j].last_center;
                Anchor {
                    marker: j,
                    last,
                    moved: c - last,
                }
            })
            .collect();
        let lasts: Vec<(usize, Point2<f64>, f64)> = undecided
            .iter()
            .map(|&i| (i, self.markers[i].last_center, window_px(&self.markers[i])))
            .collect();
        let places_at: Vec<Point2<f64>> = places.iter().map(|p| p.0).collect();
        let n = self.markers.len();
        let coherent = |a: usize, b: usize| self.coherence[a * n + b].coherent();
        let assignment = assign_anchored(&cost, cols, &lasts, &places_at, anchors, &coherent);
        undecided
            .iter()
            .zip(&assignment)
            .map(|(&i, j)| {
                let j = (*j)?;
                let best = candidates
                    .iter()
                    .zip(&column)
                    .filter(|(c, col)| c.marker == i && **col == j)
                    .min_by(|a, b| a.0.cost.total_cmp(&b.0.cost))?;
                Some((best.0.measured, best.0.context))
            })
            .collect()
    }

    /// A colour marker with a candidate at a place where another of its look has one too,
    /// both cheaper than staying unmatched (a place either could take), pays, at each of its
    /// places, the log of how much wider its normal gate is than the narrowest of theirs.
    /// The motion costs are relative to each marker's own prediction, so that alone a marker
    /// with a wide gate (one just missed, whose variance grew) pays little for a far place,
    /// and it took the place of a same-look marker predicted there (stress combined seed
    /// 16002: A, hidden behind a branch with a gate 48 px wide, took B's place 27 px from
    /// A's prediction and 4 px from B's, and held it for 8 frames while B was in plain
    /// view). Against one another the likelihoods count whole: a density
    /// spread over a wide gate is lower at every place by the ratio of the gates' areas
    /// (the normaliser of the Gaussian, the same at all of that marker's places, so its
    /// choice among them stays). The unmatched cost stays: alone, a marker with a wide gate
    /// is still found anywhere in it.
    fn price_spread(&self, cost: &mut [f64], cols: usize, undecided: &[usize]) {
        let spread = |r: usize| self.markers[undecided[r]].gate_var.max(1e-9).ln();
        let colour = |r: usize| self.markers[undecided[r]].template.is_none();
        let rows = undecided.len();
        let extra: Vec<f64> = (0..rows)
            .map(|r| {
                let rivals = (0..rows).filter(|&q| {
                    q != r
                        && colour(q)
                        && same_look(&self.markers[undecided[r]], &self.markers[undecided[q]])
                        && (0..cols).any(|j| {
                            cost[r * cols + j] < UNMATCHED_COST
                                && cost[q * cols + j] < UNMATCHED_COST
                        })
                });
                let narrowest = rivals.map(spread).fold(f64::INFINITY, f64::min);
                if colour(r) && narrowest.is_finite() {
                    (spread(r) - narrowest).max(0.0)
                } else {
                    0.0
                }
            })
            .collect();
        for (row, e) in cost.chunks_mut(cols.max(1)).zip(extra) {
            row.iter_mut().for_each(|c| *c += e);
        }
    }

    /// Whether `p` lies in marker `i`'s normal gate.
    fn in_normal_gate(&self, i: usize, p: Point2<f64>) -> bool {
        let m = &self.markers[i];
        (p - m.filter.position).norm_squared() <= GATE_CHI2 * m.gate_var
    }

    /// The extra cost of colour marker `i` taking place `p`:
    /// - a place inside another undecided same-look marker's normal gate is that marker's by
    ///   motion: reaching it only by a manoeuvre costs [`OWNED_COST`] (not for a marker
    ///   lost past its coasting frames, whose grown gate tells where it may be, not that it
    ///   is there: a marker gone for ten frames would own its whole neighbourhood);
    /// - a marker whose quick pass saw it at its prediction, only dimmer than a track needs,
    ///   is most likely still there: leaving its normal gate costs [`OWNED_COST`] too (not
    ///   after weak measurements that stood still, [`MarkerState::held_by_still_weak`]);
    /// - another marker's home beyond this one's reach, or a place far beyond that reach from
    ///   its own home, costs [`HOME_COST`].
    fn colour_cost(
        &self,
        i: usize,
        p: Point2<f64>,
        undecided: &[usize],
        quick: &[Option<Scored>],
    ) -> f64 {
        let m = &self.markers[i];
        let leaving = !self.in_normal_gate(i, p);
        let owned = undecided.iter().any(|&o| {
            let other = &self.markers[o];
            o != i
                && other.misses <= self.config.max_coast_frames
                && same_look(other, m)
                && self.in_normal_gate(o, p)
        });
        let dim_here = !m.held_by_still_weak()
            && quick[i].is_some_and(|q| {
                q.measured.confidence >= DIM_SHARE * self.config.min_confidence
                    && self.in_normal_gate(i, q.measured.center)
            });
        let jump = if leaving && (owned || dim_here) {
            OWNED_COST
        } else {
            0.0
        };
        jump + if self.at_another_home(i, p) || self.far_beyond_reach(i, p) {
            HOME_COST
        } else {
            0.0
        }
    }

    /// Whether `p` lies far beyond anywhere colour marker `i` has been tracked from its home
    /// ([`FAR_BEYOND_REACH_WINDOWS`] past its reach): a branch marker does not get there.
    pub(super) fn far_beyond_reach(&self, i: usize, p: Point2<f64>) -> bool {
        let m = &self.markers[i];
        !matches!(self.config.model, AppearanceModel::Gray { .. })
            && (p - m.home).norm() > m.reach_px + FAR_BEYOND_REACH_WINDOWS * window_px(m)
    }

    /// Whether `p` lies at another marker's home (within [`HOME_NEAR_WINDOWS`]; whatever its
    /// look: a marker's colour learnt from a half-hidden first window may not match) beyond
    /// marker `i`'s reach ([`HOME_MARGIN_WINDOWS`] past the farthest it has been found from its own
    /// home).
    fn at_another_home(&self, i: usize, p: Point2<f64>) -> bool {
        let m = &self.markers[i];
        let beyond = (p - m.home).norm() > m.reach_px + HOME_MARGIN_WINDOWS * window_px(m);
        beyond
            && self
                .markers
                .iter()
                .enumerate()
                .any(|(j, o)| j != i && (p - o.home).norm() < HOME_NEAR_WINDOWS * window_px(o))
    }

    /// What a found marker saw in its gate and was not is a look-alike to remember, unless
    /// it is some marker's place.
    fn learn_gate_look_alikes(
        &mut self,
        undecided: &[usize],
        claimed: &[Claim],
        chosen: &[Option<(Measured, Option<f64>)>],
        seen: Vec<Vec<(Point2<f64>, PixelRect)>>,
    ) {
        let places_now: Vec<Point2<f64>> = self
            .markers
            .iter()
            .map(|m| m.filter.position)
            .chain(claimed.iter().map(|c| c.2))
            .chain(chosen.iter().flatten().map(|c| c.0.center))
            .collect();
        let frame = self.frames();
        for ((&i, pick), blobs) in undecided.iter().zip(chosen).zip(seen) {
            let Some((picked, _)) = pick else { continue };
            let side = window_px(&self.markers[i]);
            let near_marker = |p: &Point2<f64>| places_now.iter().any(|q| (q - p).norm() < side);
            let m = &mut self.markers[i];
            for (p, bounds) in blobs {
                if (p - picked.center).norm() > side && !near_marker(&p) {
                    remember_distractor(m, p, bounds, side, frame);
                }
            }
        }
    }
}

/// Detection's answer for the undecided markers of a frame: per marker, its measurement and
/// context correlation or `None`, and every place it saw in its gate.
pub(super) struct Detection {
    pub(super) chosen: Vec<Option<(Measured, Option<f64>)>>,
    seen: Vec<Vec<(Point2<f64>, PixelRect)>>,
}

impl Detection {
    /// Each of the `undecided` markers' answer into `results`, as `recovered`.
    pub(super) fn record_in(&self, undecided: &[usize], results: &mut [Option<Found>]) {
        for (&i, found) in undecided.iter().zip(&self.chosen) {
            results[i] = found.map(|(q, c)| (q, TrackStatus::Recovered, c));
        }
    }
}

/// What [`Tracker::redetect`] starts from: the flagged markers with the displacement their
/// witnesses give them, and the first detection (of `undecided`).
pub(super) struct Again<'a> {
    pub(super) flagged: &'a [Flag],
    pub(super) undecided: Vec<usize>,
    pub(super) first: Detection,
    pub(super) quick: &'a [Option<Scored>],
}

/// A marker whose jump its rig-mates did not make, and where they say it went.
#[derive(Debug, Clone, Copy)]
pub(super) struct Flag {
    pub(super) marker: usize,
    pub(super) went: Went,
}

/// Where a flagged marker went, as its witnesses tell it.
#[derive(Debug, Clone, Copy)]
pub(super) enum Went {
    /// By this displacement (witnesses with a known gain).
    By(Vector2<f64>),
    /// Somewhere along this direction (unit vector; witnesses seen moving the same way, whose
    /// gain is not known yet).
    Along(Vector2<f64>),
}

/// Where a flagged marker may be found in the second detection: within `radius_px` of
/// `center`, and not against `along` from it.
pub(super) struct Confined {
    marker: usize,
    center: Point2<f64>,
    radius_px: f64,
    along: Option<Vector2<f64>>,
}

impl Confined {
    fn holds(&self, p: Point2<f64>) -> bool {
        let d = p - self.center;
        d.norm() <= self.radius_px && self.along.is_none_or(|u| d.dot(&u) >= 0.0)
    }
}

/// Whether two candidates, each `(centre, window side, the pixels it holds)`, are one place
/// that only one marker may take: closer than [`PLACE_SHARE`] of the smaller window and
/// either one blob (boxes overlapping by [`PLACE_BLOB_OVERLAP`] of their union: the same blob
/// found from two markers' gates) or closer than [`PLACE_SAME_SHARE`]. Two blobs side by side
/// are two places: two markers of one look crossing, one partly in front of the other
/// (our generator's combined condition, seed 11004: 13 px apart with windows of 33 px).
fn one_place(
    (a, side_a, holds_a): (Point2<f64>, f64, PixelRect),
    (b, side_b, holds_b): (Point2<f64>, f64, PixelRect),
) -> bool {
    let side = side_a.min(side_b);
    let near = (a - b).norm();
    let both = holds_a.intersect(&holds_b).area() as f64;
    let either = (holds_a.area() + holds_b.area()) as f64 - both;
    let one_blob = both >= PLACE_BLOB_OVERLAP * either.max(1.0);
    near < PLACE_SHARE * side && (one_blob || near < PLACE_SAME_SHARE * side)
}

/// A release streak the quick pass's region cut (`quick`, of marker `m` found in the last
/// frame), which detection's gate holds whole (among `found`): the cut part is scored (it is
/// where the marker's motion points), but the whole blob is its measurement, not the part
/// pulled back toward the prediction (see [`seen_whole`]). The cut part's centre and the
/// most confident whole blob.
fn whole_of_cut(
    m: &MarkerState,
    quick: &Measured,
    found: &[Measured],
) -> Option<(Point2<f64>, Measured)> {
    if !(quick.cut && m.last_status.found()) {
        return None;
    }
    found
        .iter()
        .filter(|c| holds_whole(c, quick))
        .max_by(|a, b| a.confidence.total_cmp(&b.confidence))
        .map(|w| (quick.center, *w))
}

/// Whether a blob whose pixels are `holds` is marker `m` smeared along its motion: the
/// marker moves at least [`STREAK_MIN_SPEED_WIDTHS`] of its width a frame, and the box
/// reaches [`STREAK_MIN_LENGTH_WIDTHS`] of that width (and the pixel the box is grown by
/// each way) along the direction of motion, farther than a marker-sized disc's box reaches
/// any way. A blurred marker is paler the longer its streak, so its pixels may change by
/// less than [`CHANGED_LEVEL`] from the frame before and pass for something that was
/// already there; a look-alike standing still does not lie along the marker's motion.
fn streak_along_motion(m: &MarkerState, holds: PixelRect) -> bool {
    let v = m.filter.velocity;
    let speed = v.norm();
    let width = m.reference.width_px;
    if !(speed.is_finite() && width.is_finite()) || speed < STREAK_MIN_SPEED_WIDTHS * width {
        return false;
    }
    let along = (v.x.abs() * f64::from(holds.width) + v.y.abs() * f64::from(holds.height)) / speed;
    along >= STREAK_MIN_LENGTH_WIDTHS * width + 2.0
}

/// The whole blob of [`whole_of_cut`] in place of the cut one it was found for.
fn seen_whole(measured: Measured, whole: Option<(Point2<f64>, Measured)>) -> Measured {
    match whole {
        Some((cut, w)) if measured.cut && measured.center == cut => w,
        _ => measured,
    }
}

/// Whether `whole` is the blob `cut` is part of, seen whole: uncut, larger, holding
/// [`WHOLE_HOLDS_SHARE`] of the cut one's box, and at least [`WHOLE_CONFIDENCE_SHARE`] as
/// confident.
fn holds_whole(whole: &Measured, cut: &Measured) -> bool {
    let (a, b) = (whole.holds.area() as f64, cut.holds.area() as f64);
    !whole.cut
        && a > b
        && whole.holds.intersect(&cut.holds).area() as f64 >= WHOLE_HOLDS_SHARE * b
        && whole.confidence >= WHOLE_CONFIDENCE_SHARE * cut.confidence
}

/// The region the quick pass weighs for marker `m` about `pred`: 3x3 windows, or with
/// `narrow` the window grown by [`NARROW_REACH_WINDOWS`] of it each way.
fn quick_region(m: &MarkerState, pred: Point2<f64>, narrow: bool) -> PixelRect {
    let (w, h) = m.size;
    let window = PixelRect::centered_at(pred, w, h);
    if narrow {
        let grow = |side: i32| (NARROW_REACH_WINDOWS * f64::from(side)).ceil() as i32;
        window.grown(grow(w), grow(h))
    } else {
        window.grown(w, h)
    }
}

/// Whether a blob whose pixels (grown by one) are `holds` reaches the edge of `region`
/// where the image goes on beyond it: the region cut it, and its centre lies nearer the
/// region's middle than the whole blob's (a release's streak running out of the quick
/// pass's region about a lagging prediction).
fn cut_by(holds: PixelRect, region: PixelRect, (width, height): (u32, u32)) -> bool {
    (holds.x < region.x && region.x > 0)
        || (holds.y < region.y && region.y > 0)
        || (holds.right() > region.right() && region.right() < i64::from(width))
        || (holds.bottom() > region.bottom() && region.bottom() < i64::from(height))
}

/// The region detection weighs for marker `m` in `gate`: the gate and a window more.
fn detection_region(m: &MarkerState, gate: &Gate) -> PixelRect {
    let (w, h) = m.size;
    let reach = gate.radius_px.ceil() as i32 + w.max(h);
    PixelRect::centered_at(gate.center, w, h).grown(reach, reach)
}

/// A marker's search gate in one frame.
pub(super) struct Gate {
    /// Variance of the opened gate (the normal gate's plus the manoeuvre's), pixels².
    wide_var: f64,
    /// The prediction, clamped into the frame.
    center: Point2<f64>,
    /// Whether the marker is predicted out of the frame after leaving it near a border.
    outside: bool,
    /// Search radius, pixels.
    pub(super) radius_px: f64,
    /// For a marker that left the frame across a border and is believed beyond it or near
    /// it: that border and how far inside it the marker can be when first seen again.
    entry: Option<(Edge, f64)>,
    /// The frame's size.
    size: (u32, u32),
}

impl Gate {
    /// Whether a candidate at `p` may be the marker: anywhere, unless it left the frame,
    /// then within the search radius of the border point it is predicted at, and within its
    /// entry depth of the border it left across.
    fn admits(&self, p: Point2<f64>) -> bool {
        (!self.outside || (p - self.center).norm() <= self.radius_px)
            && self
                .entry
                .is_none_or(|(edge, px)| edge.depth(p, self.size) <= px)
    }
}

/// A border of the frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Edge {
    Left,
    Top,
    Right,
    Bottom,
}

impl Edge {
    /// The border nearest to `p` in a frame of `size`.
    fn nearest(p: Point2<f64>, (width, height): (u32, u32)) -> Edge {
        let gaps = [
            (p.x, Edge::Left),
            (p.y, Edge::Top),
            (f64::from(width) - p.x, Edge::Right),
            (f64::from(height) - p.y, Edge::Bottom),
        ];
        gaps.into_iter()
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map_or(Edge::Top, |g| g.1)
    }

    /// How far `p` lies inside the frame from this border (negative beyond it).
    fn depth(self, p: Point2<f64>, (width, height): (u32, u32)) -> f64 {
        match self {
            Edge::Left => p.x,
            Edge::Top => p.y,
            Edge::Right => f64::from(width) - p.x,
            Edge::Bottom => f64::from(height) - p.y,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::{measured_at_point, red_squares, two_red_markers};

    #[test]
    fn two_blobs_side_by_side_are_two_places_and_one_blob_seen_twice_is_one() {
        let side = 33.0;
        // Seed 11004's pair: a streak and a disc partly behind it, 16 px apart.
        let a = (
            Point2::new(175.0, 169.0),
            side,
            PixelRect::new(159, 161, 32, 18),
        );
        let b = (
            Point2::new(167.0, 183.0),
            side,
            PixelRect::new(155, 169, 23, 25),
        );
        assert!(!one_place(a, b));
        // One blob, measured from two gates 3 px apart.
        let again = (
            Point2::new(173.0, 171.0),
            side,
            PixelRect::new(158, 161, 32, 19),
        );
        assert!(one_place(a, again));
        // Within a quarter window: one place whatever the boxes.
        let close = (
            Point2::new(170.0, 175.0),
            side,
            PixelRect::new(160, 168, 20, 15),
        );
        assert!(one_place(a, close));
        // Beyond half a window: never.
        let far = (
            Point2::new(175.0, 190.0),
            side,
            PixelRect::new(159, 161, 32, 18),
        );
        assert!(!one_place(a, far));
    }

    #[test]
    fn of_two_markers_of_one_look_at_one_place_the_one_predicted_there_narrowly_takes_it()
    -> Result<()> {
        let mut t = two_red_markers()?;
        // B predicted at the place with a narrow gate; A, just missed behind something,
        // predicted 25 px from it with a gate 48 px wide: relative to its own prediction,
        // A's motion cost there is the lower (seed 16002's 0.53 against 0.64).
        let place = Point2::new(120.0, 30.0);
        // Both have swung about the place (not beyond their reach from home).
        for m in &mut t.markers {
            m.home = Point2::new(110.0, 30.0);
            m.reach_px = 40.0;
        }
        t.markers[0].last_center = Point2::new(100.0, 30.0);
        t.markers[0].filter.position = Point2::new(95.0, 30.0);
        t.markers[0].gate_var = 2300.0;
        t.markers[1].last_center = Point2::new(121.0, 33.0);
        t.markers[1].filter.position = Point2::new(122.0, 34.0);
        t.markers[1].gate_var = 20.0;
        let candidates = [(0, 0.53), (1, 0.64)].map(|(marker, cost)| Candidate {
            marker,
            measured: measured_at_point(place),
            cost,
            context: None,
        });
        let quick = [None, None];
        let at_place = |c: &Option<(Measured, Option<f64>)>| {
            c.is_some_and(|(m, _)| (m.center - place).norm() < 1e-9)
        };
        let chosen = t.assign_places(&candidates, &[0, 1], &[], &quick);
        assert!(chosen[0].is_none() && at_place(&chosen[1]), "{chosen:?}");
        // A place only A saw is still A's: the price is the same at all its places, and
        // not on staying unmatched.
        let alone = Point2::new(80.0, 30.0);
        let mut more = candidates.to_vec();
        more.push(Candidate {
            marker: 0,
            measured: measured_at_point(alone),
            cost: 0.9,
            context: None,
        });
        let chosen = t.assign_places(&more, &[0, 1], &[], &quick);
        assert!(
            chosen[0].is_some_and(|(m, _)| (m.center - alone).norm() < 1e-9)
                && at_place(&chosen[1]),
            "{chosen:?}"
        );
        // Gates of one width: the lower cost takes the place.
        t.markers[1].gate_var = 2300.0;
        let chosen = t.assign_places(&candidates, &[0, 1], &[], &quick);
        assert!(at_place(&chosen[0]) && chosen[1].is_none(), "{chosen:?}");
        Ok(())
    }

    #[test]
    fn a_streak_the_quick_region_cuts_is_measured_whole_where_detection_holds_it() -> Result<()> {
        let mut t = two_red_markers()?;
        // A released: a streak from its place to 40 px right of it, longer than the quick
        // pass's region of 3x3 windows about its prediction reaches.
        let frame = RgbImage::from_fn(192, 64, |x, y| {
            let a = (16..=60).contains(&x) && y.abs_diff(30) <= 4;
            let b = x.abs_diff(150) <= 4 && y.abs_diff(30) <= 4;
            if a || b {
                image::Rgb([215, 25, 30])
            } else {
                image::Rgb([100, 110, 95])
            }
        });
        let region = quick_region(&t.markers[0], Point2::new(20.0, 30.0), false);
        assert!((region.right() as f64) < 60.0, "{region:?}");
        t.update(&frame, None)?;
        let o = t.tracks[0].observations[1];
        let center = o.center.unwrap_or(Point2::origin());
        // Measured at the streak's centre (38, 30), not at the part the region holds (whose
        // centre falls short of it), and, whole, a place to stand behind: found by detection
        // (`recovered`), not an estimate.
        assert!((center - Point2::new(38.0, 30.0)).norm() < 1.0, "{center}");
        assert_eq!(o.status, TrackStatus::Recovered);
        // B, whole inside its region, is tracked.
        assert_eq!(t.tracks[1].observations[1].status, TrackStatus::Tracked);
        Ok(())
    }

    #[test]
    fn a_blob_reaching_the_quick_regions_inner_edge_is_cut_and_one_at_the_image_edge_is_not() {
        let region = PixelRect::new(100, 50, 40, 40);
        let image = (640, 480);
        // Inside with a pixel to spare each way: whole.
        assert!(!cut_by(PixelRect::new(110, 60, 12, 12), region, image));
        // Reaching past the left edge (its box grown by one starts left of the region).
        assert!(cut_by(PixelRect::new(99, 60, 20, 12), region, image));
        // Past the right and the bottom edge.
        assert!(cut_by(PixelRect::new(125, 60, 16, 12), region, image));
        assert!(cut_by(PixelRect::new(110, 80, 12, 11), region, image));
        // A region at the image's corner: the image's edge cuts nothing.
        let corner = PixelRect::new(0, 0, 40, 40);
        assert!(!cut_by(PixelRect::new(-1, -1, 12, 12), corner, image));
        assert!(cut_by(PixelRect::new(30, 5, 11, 10), corner, image));
    }

    #[test]
    fn another_markers_home_beyond_ones_reach_is_not_ones_place() -> Result<()> {
        let mut t = two_red_markers()?;
        // B's home, far beyond anywhere A has been.
        assert!(t.at_another_home(0, Point2::new(151.0, 32.0)));
        // Near A's own home, or nowhere near B's: A's to take.
        assert!(!t.at_another_home(0, Point2::new(40.0, 30.0)));
        assert!(!t.at_another_home(0, Point2::new(100.0, 30.0)));
        // B's own home is B's.
        assert!(!t.at_another_home(1, Point2::new(150.0, 30.0)));
        // Once A has been found that far (its swing reaches there), it may be A.
        t.markers[0].reach_px = 125.0;
        assert!(!t.at_another_home(0, Point2::new(151.0, 32.0)));
        Ok(())
    }

    /// A marker gone out of the frame across a border comes back across it: while it is
    /// missing and predicted beyond or near that border, it is taken again only within two
    /// windows and two frames of its leaving speed (at least two windows a frame) of it
    /// (the third generator's markers pulled out of the top were taken again on look-alikes
    /// 100-250 px below the edge).
    #[test]
    fn a_marker_gone_out_across_a_border_is_taken_again_only_near_it() -> Result<()> {
        let mut t = two_red_markers()?;
        let side = window_px(&t.markers[0]);
        let (speed, y) = (4.0, 30.0);
        let entry = 2.0 * side + 2.0 * (2.0 * side);
        // Last found 3 px inside the left border, gone out of it at 4 px a frame, missing
        // for long enough that its gate about the border point reaches beyond `entry`.
        let m = &mut t.markers[0];
        m.last_center = Point2::new(3.0, y);
        m.misses = 8;
        m.exit_speed_px = speed;
        m.filter.position = Point2::new(-20.0, y);
        let gate = t.gate(0);
        assert!(gate.radius_px > entry + 10.0, "{} {entry}", gate.radius_px);
        assert!(gate.admits(Point2::new(entry - 1.0, y)));
        assert!(!gate.admits(Point2::new(entry + 2.0, y)));
        assert!(!gate.admits(Point2::new(150.0, y)));
        // Predicted back inside, deeper than that (its swing or its hold brought it back):
        // anywhere, as any missing marker.
        t.markers[0].filter.position = Point2::new(entry + 5.0, y);
        assert!(t.gate(0).admits(Point2::new(150.0, 60.0)));
        // Found in the last frame: a jump from the border is no re-entry (the gate of a
        // marker predicted out of the frame still holds it about the border point).
        let m = &mut t.markers[0];
        m.misses = 0;
        m.filter.position = Point2::new(-20.0, y);
        assert_eq!(t.gate(0).entry, None);
        // Last found in the middle of the frame: not gone out across a border.
        let m = &mut t.markers[0];
        m.misses = 8;
        m.last_center = Point2::new(96.0, y);
        assert_eq!(t.gate(0).entry, None);
        Ok(())
    }

    #[test]
    fn a_lost_markers_grown_gate_owns_no_place() -> Result<()> {
        let mut t = two_red_markers()?;
        // B, found last frame, jumped 20 px (past its normal gate) at its release; A, of
        // B's look, has coasted for a while and its normal gate has grown over B.
        let place = Point2::new(t.markers[1].home.x - 20.0, t.markers[1].home.y);
        assert!(!t.in_normal_gate(1, place));
        t.markers[0].gate_var = 1e6;
        assert!(t.in_normal_gate(0, place));
        let quick = [None, None];
        // Coasting a frame or two (within `max_coast_frames`): A may still be about to
        // appear there, so B reaching it by a manoeuvre pays the owner's price.
        t.markers[0].misses = 2;
        assert_eq!(t.colour_cost(1, place, &[0, 1], &quick), OWNED_COST);
        // Lost (past the coasting frames): its gate says where it may be, not that it is
        // there, and B's own blob costs B nothing extra.
        t.markers[0].misses = t.config.max_coast_frames + 1;
        assert_eq!(t.colour_cost(1, place, &[0, 1], &quick), 0.0);
        Ok(())
    }

    #[test]
    fn only_places_the_quick_pass_followed_widen_the_reach() -> Result<()> {
        let mut t = two_red_markers()?;
        let config = t.config.clone();
        let m = &mut t.markers[0];
        let home = m.home;
        let at = |x: f64| measured_at_point(Point2::new(home.x + x, home.y));
        // Taken by detection 90 px away (it may be a look-alike): the reach stays.
        m.found(at(90.0), TrackStatus::Recovered, &config, None, 1);
        assert!(m.reach_px < 1.0, "{}", m.reach_px);
        // Followed by the quick pass 20 px away: that is where it swings.
        m.found(at(20.0), TrackStatus::Tracked, &config, None, 2);
        assert!((m.reach_px - 20.0).abs() < 1e-9, "{}", m.reach_px);
        Ok(())
    }

    /// A red disc of radius 6 px at `marker` on grey, and a barely darker red disc of the
    /// same size, still, at (60, 40).
    fn beside_look_alike(marker: Point2<f64>) -> RgbImage {
        RgbImage::from_fn(112, 64, |x, y| {
            let on = |c: Point2<f64>| {
                (f64::from(x) - c.x).powi(2) + (f64::from(y) - c.y).powi(2) <= 36.0
            };
            if on(marker) {
                image::Rgb([215, 25, 30])
            } else if on(Point2::new(60.0, 40.0)) {
                image::Rgb([205, 28, 32])
            } else {
                image::Rgb([100, 110, 95])
            }
        })
    }

    /// Tracks the marker of [`beside_look_alike`] over `path` (its first window at
    /// (40, 20)), with or without the look-alikes it remembers; its largest error over the
    /// frames after the first and whether every one was `tracked`.
    fn track_beside(path: &[Point2<f64>], remember: bool) -> Result<(f64, bool)> {
        let init = MarkerInit {
            id: "A".into(),
            window: PixelRect::new(33, 13, 15, 15),
        };
        let first = beside_look_alike(Point2::new(40.0, 20.0));
        let mut t = Tracker::new(TrackerConfig::default(), &first, None, &[init])?;
        let mut worst: f64 = 0.0;
        for &p in path {
            if !remember {
                t.markers[0].distractors.clear();
            }
            t.update(&beside_look_alike(p), None)?;
            let c = t.tracks[0].observations.last().and_then(|o| o.center);
            worst = worst.max(c.map_or(f64::INFINITY, |c| (c - p).norm()));
        }
        let tracked = t.tracks[0].observations[1..]
            .iter()
            .all(|o| o.status == TrackStatus::Tracked);
        Ok((worst, tracked))
    }

    #[test]
    fn a_marker_at_rest_touching_a_still_look_alike_is_measured_on_its_own_part() -> Result<()> {
        // Four frames apart (the look-alike, 28 px off along the diagonal, is seen and
        // remembered), then the marker creeps toward it 0.7 px a frame until the discs
        // overlap (12 px apart is touching; the prediction is then inside the corner of the
        // look-alike's box, so masking the box would cut the marker).
        let mut path = vec![Point2::new(40.0, 20.0); 4];
        path.extend((1..=25).map(|k| {
            let d = 0.5 * f64::from(k);
            Point2::new(40.0 + d, 20.0 + d)
        }));
        let (worst, tracked) = track_beside(&path, true)?;
        assert!(worst < 1.5, "{worst}");
        assert!(tracked);
        // Without the remembered look-alike the merged blob's centroid is taken, half way
        // to the look-alike.
        let (worst, _) = track_beside(&path, false)?;
        assert!(worst > 3.0, "{worst}");
        Ok(())
    }

    /// A marker at rest alone is weighed in a narrow region, and a look-alike that comes to
    /// lie beyond that region but inside the full one is still seen (by the full region
    /// weighed every [`NARROW_RECHECK_FRAMES`] frames) and remembered, as where every frame
    /// weighs the full region; the marker stays where it is throughout.
    #[test]
    fn a_settled_marker_is_weighed_narrowly_and_still_learns_a_look_alike_beside_it() -> Result<()>
    {
        let mut t = two_red_markers()?;
        let squares = |xs: &[u32]| {
            RgbImage::from_fn(192, 64, |x, y| {
                if y.abs_diff(30) <= 4 && xs.iter().any(|&cx| x.abs_diff(cx) <= 4) {
                    image::Rgb([215, 25, 30])
                } else {
                    image::Rgb([100, 110, 95])
                }
            })
        };
        for _ in 0..10 {
            t.update(&squares(&[20, 150]), None)?;
        }
        let m = &t.markers[0];
        assert!(t.settled(0, m.filter.position), "A is not settled");
        // The look-alike 13 px right of A: outside A's narrow region (window 11 px grown by
        // 3 px each way), inside its full one (grown by 11 px).
        let look_alike = Point2::new(33.0, 30.0);
        let narrow = quick_region(m, m.filter.position, true);
        let full = quick_region(m, m.filter.position, false);
        assert!(
            !narrow.contains(29, 30) && full.contains(29, 30),
            "{narrow:?} {full:?}"
        );
        let remembered = |t: &Tracker| {
            t.markers[0]
                .distractors
                .iter()
                .any(|d| (d.at - look_alike).norm() < 1.5 && d.seen >= 2)
        };
        let mut frames_to_learn = None;
        for k in 1..=2 * NARROW_RECHECK_FRAMES {
            t.update(&squares(&[20, 33, 150]), None)?;
            if frames_to_learn.is_none() && remembered(&t) {
                frames_to_learn = Some(k);
            }
        }
        let k = frames_to_learn.expect("the look-alike is never remembered");
        assert!(k <= NARROW_RECHECK_FRAMES + 2, "{k}");
        for o in &t.tracks[0].observations {
            let c = o.center.expect("A lost");
            assert!((c - Point2::new(20.0, 30.0)).norm() < 1.0, "{c:?}");
        }
        Ok(())
    }

    #[test]
    fn a_place_far_beyond_a_markers_reach_is_not_its_own() -> Result<()> {
        let mut t = two_red_markers()?;
        let home = t.markers[0].home;
        let limit = FAR_BEYOND_REACH_WINDOWS * window_px(&t.markers[0]);
        let at = |d: f64| Point2::new(home.x, home.y + d);
        assert!(!t.far_beyond_reach(0, at(0.9 * limit)));
        assert!(t.far_beyond_reach(0, at(1.1 * limit)));
        // Tracked further out once, it reaches further.
        t.markers[0].reach_px = 0.5 * limit;
        assert!(!t.far_beyond_reach(0, at(1.1 * limit)));
        Ok(())
    }

    #[test]
    fn a_box_long_along_the_markers_motion_is_a_streak_and_a_disc_is_not() -> Result<()> {
        let mut t = two_red_markers()?;
        let m = &mut t.markers[0];
        let w = m.reference.width_px;
        assert!((7.0..=11.0).contains(&w), "{w}");
        let side = (w + 2.0).round() as i32;
        let long = (3.0 * w).round() as i32;
        // Moving left a width a frame: a box three widths long across x is a streak; the
        // same box across y, or a marker-sized disc's box, is not.
        m.filter.velocity = Vector2::new(-w, 0.0);
        assert!(streak_along_motion(m, PixelRect::new(0, 0, long, side)));
        assert!(!streak_along_motion(m, PixelRect::new(0, 0, side, long)));
        assert!(!streak_along_motion(m, PixelRect::new(0, 0, side, side)));
        // Along a diagonal a disc's box is still no streak; a long diagonal streak's is.
        m.filter.velocity = Vector2::new(w, w);
        assert!(!streak_along_motion(m, PixelRect::new(0, 0, side, side)));
        assert!(streak_along_motion(m, PixelRect::new(0, 0, long, long)));
        // A marker at rest (or creeping) draws no streak, whatever the box.
        m.filter.velocity = Vector2::new(0.1 * w, 0.0);
        assert!(!streak_along_motion(m, PixelRect::new(0, 0, long, side)));
        Ok(())
    }

    #[test]
    fn a_blob_the_quick_region_cuts_is_weighed_again_about_it_and_measured_whole() -> Result<()> {
        let mut t = two_red_markers()?;
        // A turned at the end of a fast swing: it is at x = 56 while the prediction
        // overshot to x = 40, so the region of 3x3 windows (11 px) about the prediction
        // ends inside the marker and holds only its near half.
        let frame = red_squares([56, 150]);
        let pred = Point2::new(40.0, 30.0);
        let region = quick_region(&t.markers[0], pred, false);
        assert!(region.right() > 54 && region.right() < 59, "{region:?}");
        let (best, _) = t.quick_pass(&frame, None, 0, &[pred, Point2::new(150.0, 30.0)]);
        let best = best.expect("a candidate").measured;
        // Measured whole at the marker's centre, not at the cut part's.
        assert!(
            (best.center - Point2::new(56.0, 30.0)).norm() < 0.5,
            "{}",
            best.center
        );
        assert!(!best.cut);
        Ok(())
    }
}
