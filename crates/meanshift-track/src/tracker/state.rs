//! One marker's state between frames: its motion filter, appearance statistics, swing
//! line and remembered look-alikes, and how a frame's outcome updates them.

use super::*;

impl MarkerState {
    /// A marker's state before anything is learnt from its first frame: at rest at the
    /// window's centre, its reference a filled window.
    pub(super) fn new(id: String, model: MarkerModel, lookup: Lookup, w: PixelRect) -> Self {
        let center = w.center();
        let side = f64::from(w.width.max(w.height));
        MarkerState {
            id,
            model,
            lookup,
            learnt_tables: None,
            init_size: (w.width, w.height),
            size: (w.width, w.height),
            filter: Kalman::new(center, MEASUREMENT_PX, 0.1 * side),
            swing: Swing::default(),
            acceleration_px: ACCELERATION_MIN_PX,
            last_center: center,
            home: center,
            reach_px: 0.0,
            dense_until: 0,
            signature: None,
            exchanged_at: None,
            reference: Reference {
                mass: 1.0,
                pixel_weight: 255.0,
                threshold: 255.0 * BLOB_THRESHOLD,
                pixels: w.area() as f64 * 0.5,
                width_px: side * 0.8,
                gap: 1,
            },
            depth_m: None,
            misses: 0,
            exit_speed_px: 0.0,
            restarted: false,
            clear_at: None,
            weak_run: 0,
            weak_place: None,
            trail: None,
            last_status: TrackStatus::Tracked,
            context: None,
            context_level: 1.0,
            context_var: 0.0,
            confidence_mean: 1.0,
            confidence_var: 0.0,
            gate_var: 1.0,
            distractors: Vec::new(),
            core_saturation: None,
            colour: [0.0; 3],
            shade: STREAK_MIN_SHADE,
            hue_share: STREAK_RESIDUAL[1],
            core_colour: [0.0; 3],
            template: None,
        }
    }

    /// Whether the surroundings tell this marker apart: they correlate well with
    /// themselves from frame to frame (a textured background, a fork, a target board), not
    /// only with noise.
    pub(super) fn context_informative(&self) -> bool {
        self.context.is_some() && self.context_level >= CONTEXT_MIN_LEVEL
    }

    /// The costs of this marker's candidates (each with its context correlation), scored
    /// together; candidates outside the wide gate are dropped. A cost is a negative
    /// log-likelihood relative to a perfect candidate at the prediction:
    /// - motion: the mixture of the normal gate and, with prior [`MANOEUVRE_PRIOR`], a
    ///   manoeuvre of variance `wide`;
    /// - appearance: `-ln(confidence)`, plus the shortfall from the best candidate's
    ///   confidence in units of how much this marker's own confidence varies from frame to
    ///   frame (capped), and the same for the surroundings' correlation when they are
    ///   informative; relative to the best candidate, so that a marker whose look changes as a
    ///   whole (blur, light) is not locked out;
    /// - a static look-alike's penalty;
    /// - the offset from the marker's swing line: with `use_line` (a same-look marker is
    ///   near) as it is, otherwise beyond the least offset among the candidates.
    pub(super) fn score(
        &self,
        candidates: &[(Measured, Option<f64>)],
        wide: f64,
        use_line: bool,
    ) -> Vec<Scored> {
        let best_conf = candidates
            .iter()
            .map(|c| c.0.confidence)
            .fold(0.0, f64::max);
        let best_context = candidates
            .iter()
            .filter_map(|c| c.1)
            .fold(f64::NEG_INFINITY, f64::max);
        let conf_sigma = self.confidence_sigma();
        // A gray target's surroundings that correlate far below their usual level (a
        // blurred frame) tell candidates apart less sharply. Not for colour markers: on the
        // stress sequences' tuning seeds it cost the combined condition a point.
        let spread = if self.template.is_some() {
            correlation_spread(self.context_level, best_context)
        } else {
            1.0
        };
        let context_sigma = self.context_var.sqrt().max(CONTEXT_SIGMA_MIN) * spread;
        let informative = self.context_informative();
        // With a same-look marker near, the offset counts as it is; alone, only as far as
        // it exceeds the nearest candidate's (it tells candidates apart, but does not hold a
        // marker whose release swings beside the line of its pull away from its only one).
        let line = self.swing.line();
        let least_offset = match (line, use_line) {
            (Some(l), false) => candidates
                .iter()
                .map(|c| l.offset(c.0.center).abs())
                .fold(f64::INFINITY, f64::min),
            _ => 0.0,
        };
        let normal = if self.held_by_still_weak() {
            wide.max(self.gate_var)
        } else {
            self.gate_var
        };
        candidates
            .iter()
            .filter_map(|&(measured, context)| {
                let r2 = (measured.center - self.filter.position).norm_squared();
                if r2 > GATE_CHI2 * wide.max(self.gate_var) {
                    return None;
                }
                let conf = measured.confidence;
                // A blob drawn out along its way from the last place is what a marker
                // blurred by that motion looks like: paler than a still look-alike of its
                // colour by its nature, so it is not priced for falling short of the best.
                let shortfall = if self.blurred_along(&measured) {
                    0.0
                } else {
                    (0.5 * ((best_conf - conf) / conf_sigma).powi(2)).min(APPEARANCE_CAP)
                };
                let appearance = -conf.max(1e-3).ln() + shortfall;
                let surroundings = match context {
                    Some(c) if informative => {
                        (0.5 * ((best_context - c) / context_sigma).powi(2)).min(CONTEXT_CAP)
                    }
                    _ => 0.0,
                };
                let penalty = if self.on_look_alike(&measured) {
                    DISTRACTOR_COST
                } else {
                    0.0
                };
                // A marker that swings along a line stays near it: a same-look marker
                // crossing its path is off the line where the paths are apart.
                let off_line = line.map_or(0.0, |l| {
                    let o = l.offset(measured.center).abs();
                    (0.5 * (o * o - least_offset * least_offset)).min(LINE_COST_CAP)
                });
                Some(Scored {
                    measured,
                    context,
                    cost: motion_cost(r2, normal, wide)
                        + appearance
                        + surroundings
                        + penalty
                        + off_line
                        + measured.misfit,
                })
            })
            .collect()
    }

    /// Whether `q` is a blob drawn out along its way from the last measurement, as a marker
    /// blurred by that motion is: at least [`BLURRED_KEPT_CONFIDENCE`] of the marker's usual
    /// confidence, at least [`BLURRED_MIN_WINDOWS`] from the last place, its weights'
    /// spread along their longer axis at least [`BLURRED_ELONGATION`] times that across it
    /// (standard deviations), and that axis within [`BLURRED_MAX_ANGLE_COS`]'s angle of the
    /// way (a release's streak follows the swing's curve, not the chord from the last place).
    pub(super) fn blurred_along(&self, q: &Measured) -> bool {
        let Some([xx, xy, yy]) = q.spread else {
            return false;
        };
        if q.confidence < BLURRED_KEPT_CONFIDENCE * self.confidence_mean {
            return false;
        }
        let way = q.center - self.last_center;
        let length = way.norm();
        if length < BLURRED_MIN_WINDOWS * window_px(self) {
            return false;
        }
        // The spread's principal axes: variances `mean ± root` along and across the longer.
        let (mean, half_diff) = (0.5 * (xx + yy), 0.5 * (xx - yy));
        let root = half_diff.hypot(xy);
        let (long, short) = (mean + root, mean - root);
        if long <= 0.0 || long < BLURRED_ELONGATION * BLURRED_ELONGATION * short.max(0.0) {
            return false;
        }
        // The longer axis's direction, `(xy, long - xx)` or `(long - yy, xy)` (whichever is
        // the longer vector), against the way.
        let axis = if long - xx >= long - yy {
            Vector2::new(xy, long - xx)
        } else {
            Vector2::new(long - yy, xy)
        };
        let n = axis.norm();
        n > 0.0 && (axis.dot(&way) / (n * length)).abs() >= BLURRED_MAX_ANGLE_COS
    }

    /// Whether `p` lies more than [`FAR_OFF_LINE_SPREADS`] from the marker's swing line (never
    /// without a line).
    pub(super) fn far_off_line(&self, p: Point2<f64>) -> bool {
        self.swing
            .line()
            .is_some_and(|l| l.offset(p) > FAR_OFF_LINE_SPREADS)
    }

    /// Whether a confidence is within what this marker usually shows (a blurred or paler
    /// marker may be less alike, so the check is loose: [`TYPICAL_SIGMAS`] spreads). A
    /// measurement that is not goes to detection, where it competes with other candidates.
    pub(super) fn typical(&self, confidence: f64) -> bool {
        let sigma = self.confidence_sigma();
        confidence >= self.confidence_mean - TYPICAL_SIGMAS * sigma
    }

    /// The spread of this marker's confidence: as learnt, at least [`CONFIDENCE_SIGMA_MIN`]
    /// ([`TEMPLATE_SIGMA_MIN`] for a gray target's template correlation).
    fn confidence_sigma(&self) -> f64 {
        let floor = if self.template.is_some() {
            TEMPLATE_SIGMA_MIN
        } else {
            CONFIDENCE_SIGMA_MIN
        };
        self.confidence_var.sqrt().max(floor)
    }

    /// Whether a context correlation `c` is within what this marker usually shows.
    pub(super) fn familiar(&self, c: f64) -> bool {
        let sigma = self.context_var.sqrt().max(CONTEXT_SIGMA_MIN);
        c >= self.context_level - CONTEXT_DROP.max(3.0 * sigma)
    }

    /// Learn how this marker's confidence and context correlation vary (running means and
    /// variances of the frames it was found in).
    pub(super) fn learn_appearance(&mut self, confidence: f64, context: Option<f64>) {
        let d = confidence - self.confidence_mean;
        self.confidence_mean += APPEARANCE_RATE * d;
        self.confidence_var += APPEARANCE_RATE * (d * d - self.confidence_var);
        if let Some(c) = context {
            let d = c - self.context_level;
            self.context_level += APPEARANCE_RATE * d;
            self.context_var += APPEARANCE_RATE * (d * d - self.context_var);
        }
    }

    /// Given a state that followed something else (see `Tracker::repair_swaps`): its
    /// velocity is forgotten and it is looked for as a marker missing for
    /// [`STOP_AFTER_MISSES`] frames, so that where it is found next is not taken for a jump
    /// it made in one frame (a 130 px recovery became a velocity of 95 px a frame, which
    /// carried the prediction out of the frame and the marker was lost for 6 frames).
    pub(super) fn whereabouts_unknown(&mut self) {
        self.filter.stop(window_px(self));
        self.misses = self.misses.max(STOP_AFTER_MISSES);
        if self.last_status.found() {
            self.last_status = TrackStatus::Predicted;
        }
    }

    /// Whether the track has stood still on weak measurements for [`WEAK_STILL_FRAMES`]
    /// frames in a row (each within [`WEAK_STILL_WINDOWS`] of the one before), more than
    /// [`HOME_NEAR_WINDOWS`] from its home. A marker measured weakly because it is blurred
    /// is moving, and one at rest (weak because half hidden) stands at its home; one that
    /// stands still on weak measurements away from it is more likely held by a still
    /// look-alike it slid onto at a turn (a
    /// paler disc beside a swing's end held one for 28 frames while the marker swung past in
    /// plain view), and a prediction that follows the look-alike keeps choosing it. So then
    /// the quick pass's result is not accepted alone (detection looks in the gate), the
    /// prediction counts no more than the manoeuvre's gate in the motion cost, and the weak
    /// place does not hold the marker as a dim sighting of it would
    /// (`Tracker::colour_cost`).
    pub(super) fn held_by_still_weak(&self) -> bool {
        self.weak_place.is_some_and(|(at, still)| {
            still >= WEAK_STILL_FRAMES
                && (at - self.home).norm() > HOME_NEAR_WINDOWS * window_px(self)
        })
    }

    /// Frames the search has gone on: misses, or frames followed only on weak measurements
    /// (a still look-alike taken at a release's turn kept the gate at its normal size for
    /// seven frames while the marker swung 150 px away).
    pub(super) fn searching(&self) -> usize {
        self.misses.max(self.weak_run)
    }

    /// True when `at` is on a static look-alike of this marker.
    #[cfg(test)]
    pub(super) fn on_distractor(&self, at: Point2<f64>) -> bool {
        let side = window_px(self);
        self.distractors
            .iter()
            .any(|d| d.seen >= 2 && (d.at - at).norm() < (DISTRACTOR_RADIUS * side).max(2.0))
    }

    /// True when measurement `q` is a static look-alike of this marker: centred on one
    /// (within [`DISTRACTOR_RADIUS`] windows), or a part of one, its blob's box inside the
    /// look-alike's and at least [`LOOK_ALIKE_PART_SHARE`] of it (a look-alike that a twig
    /// cuts in two is seen as either part, each centred elsewhere). A look-alike paler than
    /// the marker is not the measurement of a marker found in the last frame and moving
    /// (faster than [`RESTING_WINDOWS_PER_FRAME`]): in its box only pixels more saturated
    /// than it count ([`MarkerState::paler_boxes`]), so what is measured there is the marker
    /// passing over it. For a marker being looked for, or a track standing still, it still
    /// is: noise, flicker and JPEG lift a few of the look-alike's pixels over the floor, a
    /// weak fragment that must not be taken for the marker.
    pub(super) fn on_look_alike(&self, q: &Measured) -> bool {
        let near = (DISTRACTOR_RADIUS * window_px(self)).max(2.0);
        let passing = self.last_status.found()
            && self.filter.velocity.norm() > RESTING_WINDOWS_PER_FRAME * window_px(self);
        self.distractors
            .iter()
            .filter(|d| d.seen >= 2 && !(passing && self.paler_floor(d).is_some()))
            .any(|d| {
                (d.at - q.center).norm() < near
                    || (q.holds.intersect(&d.bounds) == q.holds
                        && q.holds.area() as f64 >= LOOK_ALIKE_PART_SHARE * d.bounds.area() as f64)
            })
    }

    /// The saturation floor (8-bit levels) that keeps look-alike `d` out of this marker's
    /// weights in its box: halfway between the two cores, when `d` is paler by at least
    /// [`TOUCHING_PALER_LEVELS`] (both measured on the first frame; `None` otherwise).
    fn paler_floor(&self, d: &Distractor) -> Option<u8> {
        let (core, s) = (self.core_saturation?, d.saturation?);
        (core - s >= TOUCHING_PALER_LEVELS)
            .then(|| (0.5 * (core + s)).round().clamp(0.0, 255.0) as u8)
    }

    /// The places of this marker's static look-alikes more than half a window from `pred`:
    /// where the marker is not predicted to be on them, a blob holding one is the marker and
    /// the look-alike touching (see [`candidates_in`]).
    pub(super) fn look_alikes_away(&self, pred: Point2<f64>) -> Vec<Point2<f64>> {
        let half = 0.5 * window_px(self);
        if self.misses > 0
            || self.filter.velocity.norm() > RESTING_WINDOWS_PER_FRAME * window_px(self)
        {
            return Vec::new();
        }
        self.distractors
            .iter()
            .filter(|d| d.seen >= 2 && !d.shared && (d.at - pred).norm() > half)
            // A paler one is kept out of the weights by its floor: its blob is not the pair.
            .filter(|d| self.paler_floor(d).is_none())
            .map(|d| d.at)
            .collect()
    }

    /// The boxes of this marker's static look-alikes in `region` that it is not predicted to
    /// be on: their pixels do not count, so that a marker passing one is not pulled onto it.
    /// Where it is predicted on a paler one, that one's box has a saturation floor instead
    /// ([`MarkerState::paler_boxes`]).
    pub(super) fn static_masks(&self, region: PixelRect, pred: Point2<f64>) -> Vec<PixelRect> {
        let (hw, hh) = (self.size.0 / 4, self.size.1 / 4);
        self.distractors
            .iter()
            .filter(|d| d.seen >= 2 && !d.shared && d.bounds.intersect(&region).area() > 0)
            .filter(|d| {
                let b = d.bounds.grown(hw, hh);
                !(pred.x >= f64::from(b.x)
                    && pred.y >= f64::from(b.y)
                    && pred.x < b.right() as f64
                    && pred.y < b.bottom() as f64)
            })
            .map(|d| d.bounds)
            .collect()
    }

    /// The boxes of this marker's static look-alikes in `region` that it is predicted on
    /// (not among the boxes `masked` whole, which hold what [`MarkerState::static_masks`]
    /// gave) and that are paler than the marker by at least [`TOUCHING_PALER_LEVELS`], each with a saturation floor halfway between the two
    /// ([`MarkerState::paler_floor`]): in them only the marker's own pixels count, so that a
    /// marker passing over a paler look-alike of its hue is measured on itself, not on the
    /// pair. Elsewhere the box is masked whole: under flicker and JPEG some of a look-alike's
    /// pixels rise over the floor, and a track thrown near it must not settle on them.
    pub(super) fn paler_boxes(
        &self,
        region: PixelRect,
        masked: &[PixelRect],
    ) -> Vec<(PixelRect, u8)> {
        self.distractors
            .iter()
            .filter(|d| d.seen >= 2 && !d.shared && d.bounds.intersect(&region).area() > 0)
            .filter(|d| !masked.contains(&d.bounds))
            .filter_map(|d| self.paler_floor(d).map(|floor| (d.bounds, floor)))
            .collect()
    }

    /// One frame ahead: the motion model, then held in the frame of `size` (see
    /// [`MarkerState::held_in_frame`]).
    pub(super) fn predict(&mut self, config: &TrackerConfig, size: (u32, u32), frame: u64) {
        self.filter = self.predicted(config, size, frame);
    }

    /// The filter one frame ahead, as [`MarkerState::predict`] leaves it, without changing
    /// the marker: what the next frame will look at is known before it comes. `frame` is
    /// the index of the frame predicted: a marker that was not found in the frame before and
    /// has no swing learnt yet is extrapolated on the acceleration of its last positions
    /// ([`crate::swing::Swing::extrapolate`]), so that one speeding up in a pull and hidden
    /// behind another of its look for a frame or two is looked for where it went, not where
    /// a constant (and, while coasting, decaying) velocity leaves it behind.
    pub(super) fn predicted(&self, config: &TrackerConfig, size: (u32, u32), frame: u64) -> Kalman {
        let mut f = self.filter;
        match config.motion {
            MotionModel::Static => {
                f.stop(0.0);
                f.predict(self.acceleration_px);
            }
            MotionModel::ConstantVelocity { .. } => {
                let (p, v) = (f.position, f.velocity);
                f.predict(self.acceleration_px);
                // A swing turns: the learnt acceleration bends the prediction.
                if let Some(a) = self.swing.acceleration(p, v) {
                    f.position += a;
                    f.velocity += a;
                } else if !self.last_status.found()
                    && let Some((q, w)) = self.swing.extrapolate(frame)
                {
                    // Coasting before any swing is learnt: on the track's own acceleration.
                    f.position = q;
                    f.velocity = w;
                }
            }
        }
        self.held_in_frame(f, size)
    }

    /// A colour marker predicted out of the frame although its swing about its home stays
    /// inside it (the disc of the farthest it was tracked from home and
    /// [`HOLD_REACH_WINDOWS`] more lies within the frame) has not left: the constant
    /// velocity was carried out of a turn (a swing of 5–8 Hz at 30 fps turns within a
    /// frame or two). Its prediction is brought back to that disc's edge, still, so that it
    /// is looked for in the frame rather than as a marker that left across the border.
    /// Returns `f`, so held.
    fn held_in_frame(&self, mut f: Kalman, (width, height): (u32, u32)) -> Kalman {
        if self.template.is_some() {
            return f;
        }
        let p = f.position;
        if p.x >= 0.0 && p.y >= 0.0 && p.x <= f64::from(width) && p.y <= f64::from(height) {
            return f;
        }
        let side = window_px(self);
        let disc = self.reach_px + HOLD_REACH_WINDOWS * side;
        let home = self.home;
        let home_in_frame = home.x - disc >= 0.0
            && home.y - disc >= 0.0
            && home.x + disc <= f64::from(width)
            && home.y + disc <= f64::from(height);
        let out = p - home;
        if !home_in_frame || out.norm() <= disc {
            return f;
        }
        f.position = home + out * (disc / out.norm());
        f.stop(side);
        f
    }

    /// Record a measurement.
    pub(super) fn found(
        &mut self,
        q: Measured,
        status: TrackStatus,
        config: &TrackerConfig,
        depth: Option<&DepthView<'_>>,
        frame: u64,
    ) -> Observation {
        let innovation = (q.center - self.filter.position).norm_squared();
        self.filter.update(q.center, MEASUREMENT_PX);
        if status == TrackStatus::Tracked {
            // Only where the quick pass followed it: a place detection took it to may be a
            // look-alike, and must not widen where it may be taken next.
            self.reach_px = self.reach_px.max((q.center - self.home).norm());
        }
        let side = window_px(self);
        self.restarted = self.searching() >= STOP_AFTER_MISSES && innovation > side * side;
        if self.restarted {
            // Found again after frames of coasting (missed, or followed only on weak
            // measurements), a window or more from where the coasting put it: that jump is not
            // a velocity (it made a marker found again at the end of a swing fly off the
            // frame), and where the swing is now in its cycle is unknown.
            self.filter.stop(side);
        }
        if let MotionModel::ConstantVelocity {
            min_acceleration_px,
        } = config.motion
        {
            // The model expects as much change as it has recently seen; a recovery after a
            // miss says little about the acceleration, and is left out.
            if self.misses == 0 {
                let a2 = self.acceleration_px * self.acceleration_px;
                let next = a2 + ACCELERATION_RATE * (0.5 * innovation - a2);
                self.acceleration_px = next.sqrt().max(min_acceleration_px);
            }
        } else {
            self.filter.stop(0.0);
        }
        if config.window == WindowMode::Adaptive
            && let Some(m) = q.moments
            && m.m00 > 0.0
        {
            let (w, h) = Axes::of(&m).window_size();
            let (w0, h0) = self.init_size;
            self.size = (
                w.clamp((w0 / 2).max(1), w0 * 2),
                h.clamp((h0 / 2).max(1), h0 * 2),
            );
        }
        if let Some(d) = depth
            && let Some(dm) = window_depth(d, q.window)
        {
            self.depth_m = Some(dm);
        }
        self.last_center = q.center;
        self.misses = 0;
        self.last_status = status;
        // A place detection (or a weak measurement) put far off the line the marker swings
        // along is not learnt as part of its swing: were it a look-alike, the line it would
        // bend or erase is what tells the marker's own place from it next frame.
        let off_line = status != TrackStatus::Tracked && self.far_off_line(q.center);
        if !off_line {
            self.swing.record(frame, q.center);
        }
        Observation {
            center: Some(q.center),
            window: q.window,
            status,
            confidence: q.confidence,
        }
    }

    /// Not found, and merged with a marker of the same look: it coasts on its own motion
    /// (the two cross) and the frame does not count as a miss, so that it is neither given
    /// up while hidden in the other's blob nor looked for far away, and is taken up again
    /// as soon as it shows.
    pub(super) fn merged(&mut self, (width, height): (u32, u32)) -> Observation {
        if self.filter.velocity.norm() > MERGED_STEADY_WINDOWS * window_px(self) {
            self.filter.velocity *= COAST_VELOCITY_DECAY;
        }
        let pred = clamp_into(self.filter.position, width, height);
        self.last_status = TrackStatus::Predicted;
        Observation {
            center: Some(pred),
            window: PixelRect::centered_at(pred, self.size.0, self.size.1),
            status: TrackStatus::Predicted,
            confidence: 0.0,
        }
    }

    /// No measurement this frame: coast, then lose.
    pub(super) fn missed(
        &mut self,
        config: &TrackerConfig,
        (width, height): (u32, u32),
    ) -> Observation {
        self.misses += 1;
        if self.misses == 1 {
            self.exit_speed_px = self.filter.velocity.norm();
        }
        self.filter.velocity *= COAST_VELOCITY_DECAY;
        let pred = clamp_into(self.filter.position, width, height);
        let lost = self.misses > config.max_coast_frames;
        self.last_status = if lost {
            TrackStatus::Lost
        } else {
            TrackStatus::Predicted
        };
        Observation {
            center: (!lost).then_some(pred),
            window: PixelRect::centered_at(pred, self.size.0, self.size.1),
            status: self.last_status,
            confidence: 0.0,
        }
    }
}

/// Whether two markers look alike: one appearance model and colours within
/// [`SAME_LOOK_RGB`] (gray targets: any two).
pub(super) fn same_look(a: &MarkerState, b: &MarkerState) -> bool {
    let d2: f32 = a
        .colour
        .iter()
        .zip(&b.colour)
        .map(|(x, y)| (x - y) * (x - y))
        .sum();
    d2 <= SAME_LOOK_RGB * SAME_LOOK_RGB
}

/// Whether a marker of the same look is predicted within [`CROWD_WINDOWS`] windows of marker
/// `i`: only then can the two be confused, and only then does the swing line count (alone,
/// a marker whose release swings beside the line of its pull must not be held to it).
pub(super) fn crowded(markers: &[MarkerState], i: usize) -> bool {
    let m = &markers[i];
    let reach = CROWD_WINDOWS * window_px(m);
    markers.iter().enumerate().any(|(j, o)| {
        j != i
            && same_look(m, o)
            && (o.filter.position - m.filter.position).norm()
                < reach.max(CROWD_WINDOWS * window_px(o))
    })
}

/// Where the markers of marker `i`'s look within [`CROWD_WINDOWS`] of it were found last
/// and are predicted: the places a blob of two touching markers may hold `i`'s partner.
pub(super) fn partners_of(markers: &[MarkerState], i: usize) -> Vec<Point2<f64>> {
    let m = &markers[i];
    let reach = CROWD_WINDOWS * window_px(m);
    markers
        .iter()
        .enumerate()
        .filter(|&(j, o)| j != i && same_look(m, o))
        .flat_map(|(_, o)| [o.last_center, o.filter.position])
        .filter(|p| (p - m.filter.position).norm() < reach || (p - m.last_center).norm() < reach)
        .collect()
}

/// Window size (the larger side) of a marker, pixels.
pub(super) fn window_px(m: &MarkerState) -> f64 {
    f64::from(m.size.0.max(m.size.1))
}

/// Remember a look-alike at `p`: seen again where it was (within [`STATIC_PX`]), it counts
/// once more; seen elsewhere nearby (partly covered, or moving), its count halves, and below
/// 2 it starts over there. The oldest is forgotten past the limit. `frame` is the frame it
/// is seen in.
pub(super) fn remember_distractor(
    m: &mut MarkerState,
    p: Point2<f64>,
    bounds: PixelRect,
    side: f64,
    frame: usize,
) {
    if let Some(d) = m
        .distractors
        .iter_mut()
        .find(|d| (d.at - p).norm() < (DISTRACTOR_RADIUS * side).max(2.0))
    {
        if (d.at - p).norm() <= STATIC_PX {
            d.seen = d.seen.saturating_add(1).min(MAX_SEEN);
            if d.seen >= 2 && d.static_frame.is_none() {
                d.static_frame = Some(frame);
            }
        } else {
            d.seen /= 2;
            if d.seen < 2 {
                *d = Distractor {
                    at: p,
                    bounds,
                    seen: 1,
                    first_frame: frame,
                    static_frame: None,
                    saturation: None,
                    shared: false,
                };
            }
        }
        return;
    }
    if m.distractors.len() >= MAX_DISTRACTORS {
        // The oldest of the least seen goes: a static look-alike outlasts places seen once.
        let least = m.distractors.iter().map(|d| d.seen).min().unwrap_or(0);
        if let Some(k) = m.distractors.iter().position(|d| d.seen == least) {
            m.distractors.remove(k);
        }
    }
    m.distractors.push(Distractor {
        at: p,
        bounds,
        seen: 1,
        first_frame: frame,
        static_frame: None,
        saturation: None,
        shared: false,
    });
}

/// How much wider the spread of a correlation is at `now` than at the `usual` level: the
/// sampling spread of a correlation coefficient goes as `1 - rho^2` (Fisher 1915), so
/// surroundings that correlate 0.74 in a blurred frame, where they usually correlate 0.98,
/// tell candidates apart about twelve times less sharply. Never below 1.
pub(super) fn correlation_spread(usual: f64, now: f64) -> f64 {
    let at = |rho: f64| 1.0 - rho.clamp(0.0, 1.0).powi(2);
    (at(now) / at(usual).max(CORRELATION_SPREAD_FLOOR)).max(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::{measured_at_point, two_red_markers};

    #[test]
    fn a_prediction_thrown_out_of_the_frame_is_held_where_the_marker_swings() -> Result<()> {
        let mut t = two_red_markers()?;
        let size = (t.width, t.height);
        let m = &mut t.markers[0];
        let home = m.home;
        let disc = m.reach_px + HOLD_REACH_WINDOWS * window_px(m);
        // Carried 50 px left of its home, off the 192x64 frame, at 60 px a frame.
        m.filter.position = home + Vector2::new(-50.0, 0.0);
        m.filter.velocity = Vector2::new(-60.0, 0.0);
        m.filter = m.held_in_frame(m.filter, size);
        assert!((m.filter.position - (home + Vector2::new(-disc, 0.0))).norm() < 1e-9);
        assert_eq!(m.filter.velocity, Vector2::zeros());
        // A prediction inside the frame is left alone, however far from home.
        let inside = home + Vector2::new(100.0, 20.0);
        m.filter.position = inside;
        m.filter.velocity = Vector2::new(5.0, 0.0);
        m.filter = m.held_in_frame(m.filter, size);
        assert_eq!(m.filter.position, inside);
        // A marker tracked out to the border may have left the frame: not held.
        m.reach_px = home.x;
        let off = home + Vector2::new(-50.0, 0.0);
        m.filter.position = off;
        m.filter = m.held_in_frame(m.filter, size);
        assert_eq!(m.filter.position, off);
        Ok(())
    }

    #[test]
    fn a_marker_coasting_before_its_swing_is_learnt_goes_on_at_its_acceleration() -> Result<()> {
        let mut t = two_red_markers()?;
        let (config, size) = (t.config.clone(), (t.width, t.height));
        let m = &mut t.markers[0];
        let home = m.home;
        let at = |f: u64| {
            let s = f as f64;
            Point2::new(home.x + 0.5 * s * s, home.y)
        };
        // Speeding up at 1 px/frame² for six frames, found in each: too few for a swing.
        for f in 1..=6u64 {
            m.predict(&config, size, f);
            m.found(
                measured_at_point(at(f)),
                TrackStatus::Tracked,
                &config,
                None,
                f,
            );
        }
        // Frame 7 is predicted as the filter has it (the marker was found in frame 6); it
        // is not found there (hidden), and frame 8 goes on at the acceleration.
        m.predict(&config, size, 7);
        m.merged(size);
        let coasting = m.predicted(&config, size, 8).position;
        assert!((coasting - at(8)).norm() < 0.5, "{coasting} vs {}", at(8));
        // What the filter's velocity, decayed as a missed marker's is, would give: half a
        // window behind (a merged marker this slow keeps its velocity, so its filter is ahead
        // of that).
        let mut decayed = m.filter;
        decayed.velocity *= COAST_VELOCITY_DECAY;
        decayed.predict(m.acceleration_px);
        assert!(
            (decayed.position - at(8)).norm() > 4.0,
            "{}",
            decayed.position
        );
        // Found in the frame before, the filter predicts as it always has.
        let mut cv = m.filter;
        cv.predict(m.acceleration_px);
        m.last_status = TrackStatus::Tracked;
        assert_eq!(m.predicted(&config, size, 8).position, cv.position);
        Ok(())
    }

    #[test]
    fn a_merged_marker_keeps_a_crossing_speed_and_slows_from_a_faster_one() -> Result<()> {
        let t = two_red_markers()?;
        let size = (t.width, t.height);
        let side = window_px(&t.markers[0]);
        for (windows_per_frame, kept) in [(0.3, 1.0), (0.45, 1.0), (1.0, COAST_VELOCITY_DECAY)] {
            let mut m = t.markers[0].clone();
            let v = Vector2::new(windows_per_frame * side, 0.0);
            m.filter.velocity = v;
            let at = m.filter.position;
            m.merged(size);
            assert_eq!(
                m.filter.velocity,
                v * kept,
                "{windows_per_frame} windows a frame"
            );
            // Merged is not missed: it stays where it was put, with no miss counted.
            assert_eq!(m.filter.position, at);
            assert_eq!(m.misses, 0);
        }
        Ok(())
    }

    #[test]
    fn a_place_taken_far_off_the_swing_line_is_not_learnt_as_the_swing() -> Result<()> {
        let mut t = two_red_markers()?;
        let config = t.config.clone();
        let m = &mut t.markers[0];
        let home = m.home;
        let at = |x: f64, y: f64| measured_at_point(Point2::new(home.x + x, home.y + y));
        // Followed by the quick pass through a swing of ±20 px along x.
        for f in 1..=20u64 {
            let x = 20.0 * (0.6 * f as f64).sin();
            m.found(at(x, 0.0), TrackStatus::Tracked, &config, None, f);
        }
        let line = m.swing.line().expect("a swing along x has a line");
        // Detection takes it 40 px across the line (8 spreads): not part of the swing.
        m.found(at(0.0, 40.0), TrackStatus::Recovered, &config, None, 21);
        assert_eq!(m.swing.line(), Some(line));
        // Detection takes it back onto the line: recorded.
        m.found(at(5.0, 0.0), TrackStatus::Recovered, &config, None, 22);
        let refit = m.swing.line().expect("still a line");
        assert_ne!(refit, line);
        // The quick pass follows it across the line: that is where it is, recorded.
        m.found(at(0.0, 40.0), TrackStatus::Tracked, &config, None, 23);
        assert_ne!(m.swing.line(), Some(refit));
        Ok(())
    }

    #[test]
    fn a_streak_along_its_way_is_not_priced_for_being_paler_than_a_still_look_alike() -> Result<()>
    {
        let t = two_red_markers()?;
        let mut m = t.markers[0].clone();
        let last = m.last_center;
        let side = window_px(&m);
        // Learnt as steady: its confidence barely moves.
        (m.confidence_mean, m.confidence_var) = (0.93, 0.0);
        let blob = |dx: f64, dy: f64, confidence: f64, spread: [f64; 3]| Measured {
            confidence,
            spread: Some(spread),
            ..measured_at_point(last + Vector2::new(dx, dy))
        };
        // A release's first streak, drawn out along its way (variances 34 and 7 px², the
        // longer axis 30 degrees off the chord), and a crisp look-alike disc farther off.
        let (a, c) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let (long, short) = (34.0, 7.0);
        let tilted = [
            long * a * a + short * c * c,
            (long - short) * a * c,
            long * c * c + short * a * a,
        ];
        let streak = blob(1.2 * side, 0.0, 0.69, tilted);
        let disc = blob(-0.5 * side, -2.0 * side, 0.98, [6.5, 0.0, 6.3]);
        assert!(m.blurred_along(&streak));
        assert!(!m.blurred_along(&disc), "a disc is not drawn out");
        // Not when the blob lies across its way, is too near to have moved, or is a plain
        // mean-shift mode (no blob).
        assert!(!m.blurred_along(&blob(0.0, 1.2 * side, 0.69, tilted)));
        assert!(!m.blurred_along(&blob(0.3 * side, 0.0, 0.69, tilted)));
        let mode = Measured {
            spread: None,
            ..streak
        };
        assert!(!m.blurred_along(&mode));
        // Nor a drawn-out blob far fainter than the marker (a twig's smear).
        assert!(!m.blurred_along(&blob(1.2 * side, 0.0, 0.38, tilted)));
        // Both outside the normal gate and inside the manoeuvre's: the streak is chosen,
        // while as a round blob of its paleness it would not be.
        m.gate_var = 4.0;
        let wide = 400.0;
        let cost = |q: Measured, others: &[Measured]| {
            let all: Vec<(Measured, Option<f64>)> = std::iter::once(q)
                .chain(others.iter().copied())
                .map(|q| (q, None))
                .collect();
            m.score(&all, wide, false)[0].cost
        };
        assert!(cost(streak, &[disc]) < cost(disc, &[streak]));
        let round = blob(1.2 * side, 0.0, 0.69, [6.5, 0.0, 6.3]);
        assert!(cost(round, &[disc]) > cost(disc, &[round]));
        Ok(())
    }
}
