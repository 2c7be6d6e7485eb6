//! Starting to track: a marker's appearance learnt from its first window, and the
//! look-alikes already in the first frame.

use super::*;

impl Tracker {
    /// Learn marker `init` from the first frame (its model, reference blob, colour and
    /// surroundings) and start its track there. Returns the blobs of its look over the whole
    /// first frame when learning it found them (see [`Tracker::background_floor`]), for
    /// [`Tracker::learn_distractors`].
    pub(super) fn add_marker(
        &mut self,
        frame: &RgbImage,
        depth: Option<&DepthView<'_>>,
        init: &MarkerInit,
        inits: &[MarkerInit],
    ) -> Result<Option<Vec<Measured>>> {
        let w = init.window;
        self.check_window(init)?;
        let config = &self.config;
        let model = MarkerModel::learn(
            &init.id,
            frame,
            w,
            &config.model,
            &config.hsv_mask,
            config.background_weighting,
        )?;
        let mask = marker_mask(frame, w, &config.model, &config.hsv_mask);
        let (mut state, mut measured) = self.learn(frame, depth, init, model.clone(), &mask);
        // A paler look-alike touching the marker, learnt as one blob with it: the marker is
        // learnt again with a saturation floor between the two, which keeps the look-alike
        // out of its weights (its blurred streaks still count by their blend with the
        // background), and starts at its own centre.
        // Paler pixels of its hue elsewhere in the frame (reddish bark it may swing onto)
        // are kept out the same way.
        let mut first_blobs = None;
        let floor = match self.paler_floor(frame, &state, &measured, w, &mask) {
            Some(floor) => Some(floor),
            None => {
                let (floor, blobs) =
                    self.background_floor(frame, depth, &state, &measured, &mask, inits);
                first_blobs = blobs;
                floor
            }
        };
        // Nothing paler of its look to keep out on the first frame: its own floor still
        // keeps out what is half as saturated as it, which the frames to come may bring
        // beside it (see `Tracker::own_floor`). The first frame's blobs of its look are then
        // those the raised floor keeps.
        let floor = floor.or_else(|| {
            let floor = self.own_floor(frame, &state, &measured, &mask)?;
            if let Some(blobs) = first_blobs.as_mut() {
                let side = window_px(&state);
                blobs.retain(|b: &Measured| {
                    core_saturation(frame, b.center, side).is_some_and(|s| s >= f64::from(floor))
                });
            }
            Some(floor)
        });
        if let Some(floor) = floor {
            let raised = ChannelRange {
                lower: [mask.lower[0], floor, mask.lower[2]],
                upper: mask.upper,
            };
            (state, measured) = self.learn(frame, depth, init, model, &raised);
        }
        let observation = Observation {
            center: Some(measured.center),
            window: measured.window,
            status: TrackStatus::Tracked,
            confidence: measured.confidence,
        };
        if self.raises_floors() {
            state.core_saturation = core_saturation(frame, measured.center, window_px(&state));
        }
        state.last_center = measured.center;
        state.home = measured.center;
        state.filter.position = measured.center;
        if self.config.context_check {
            state.context = Some(Template::learn(
                frame,
                measured.center,
                (w.width * CONTEXT_SCALE) as usize,
                (w.height * CONTEXT_SCALE) as usize,
            ));
        }
        self.markers.push(state);
        self.tracks.push(Track {
            id: init.id.clone(),
            observations: vec![observation],
        });
        Ok(first_blobs)
    }

    /// Marker `init`'s state learnt from the first frame with `model` under `mask` (its
    /// reference blob and colour), and where it is on that frame.
    fn learn(
        &mut self,
        frame: &RgbImage,
        depth: Option<&DepthView<'_>>,
        init: &MarkerInit,
        model: MarkerModel,
        mask: &ChannelRange,
    ) -> (MarkerState, Measured) {
        let w = init.window;
        let config = &self.config;
        let lookup = Lookup::new(&config.model, &model, mask);
        let center = w.center();
        let mut state = MarkerState::new(init.id.clone(), model, lookup, w);
        // The reference: the window's mass, and the blob of the marker in it.
        state.depth_m = depth.and_then(|d| window_depth(d, w));
        let region = w.grown(w.width, w.height);
        fill(
            &mut self.region,
            config,
            &state,
            frame,
            None,
            depth,
            region,
            &[],
            &[],
            false,
        );
        state.reference.mass = self.region.mass(w).max(1.0);
        learn_blob(&mut state, &self.region, &mut self.labeler, w);
        state.reference.gap = state.reference.gap.max(hole_gap(frame, w));
        state.colour = mean_colour(frame, &self.region, w, state.reference.threshold);
        if let Some(darkest) = darkest_shade(
            frame,
            &self.region,
            w,
            state.reference.threshold,
            state.colour,
        ) {
            state.shade = darkest.min(STREAK_MIN_SHADE);
        }
        state.core_colour = core_colour(frame, &self.region, w, state.reference.threshold);
        let colours = [state.colour, state.core_colour];
        if let Some(share) = rim_hue_share(frame, center, state.reference.width_px, colours) {
            state.hue_share = share;
        }
        let mode = if config.recovery {
            // Where mean-shift over the weights blobs are measured on puts the marker, for
            // every model: the kernel model's Bhattacharyya mean-shift, on a target histogram
            // weighed against the background, runs off toward the window's rarest colours
            // (a white target's black dot on a white wall: 12 px on the real vibration
            // frames), which a measurement never does.
            self.region
                .weights_locate(&config.criteria, state.reference.mass, center, state.size)
        } else {
            self.region.locate(
                &state.model,
                &config.criteria,
                state.reference.mass,
                center,
                state.size,
            )
        };
        let gray = matches!(config.model, AppearanceModel::Gray { .. });
        let measured = if config.recovery && gray {
            // A black-and-white target is located by its own window from here on; centre the
            // template on the target as mean-shift sees it.
            state.template = Some(Template::learn(
                frame,
                mode.center,
                w.width as usize,
                w.height as usize,
            ));
            Measured {
                confidence: 1.0,
                ..plain(&self.region, mode)
            }
        } else if config.recovery {
            let near = |c: &Measured| (c.center - mode.center).norm();
            let nearest = candidates_in(
                &mut self.region,
                &mut self.labeler,
                &state,
                &Near::default(),
            )
            .into_iter()
            .filter(|c| c.holds.intersect(&w).area() > 0)
            .min_by(|a, b| near(a).total_cmp(&near(b)));
            match nearest {
                // A blob whose centre mean-shift in the window does not come near is the
                // marker merged with something touching it (a look-alike beside it): the
                // marker is what the window holds, and mean-shift's centre is its centre.
                Some(c) if near(&c) > INIT_MERGED_WINDOWS * window_px(&state) => {
                    learn_blob_in_window(&mut state, &self.region, w);
                    plain(&self.region, mode)
                }
                Some(c) => c,
                None => plain(&self.region, mode),
            }
        } else {
            plain(&self.region, mode)
        };
        (state, measured)
    }

    /// The saturation floor (8-bit levels) that keeps a paler look-alike touching a colour
    /// marker out of its weights, when the marker's first blob holds one (see
    /// [`paler_part`]): halfway between the marker's core saturation and the look-alike's
    /// median, never below `mask`'s. `None` for one-channel and kernel models, and for a
    /// blob without such a part. The core is the more saturated of the blob's centre and the
    /// first `window`'s: a look-alike touching the marker pulls the blob's centre toward it,
    /// where the core reads paler than the marker (on a crossing sequence 198 against the
    /// marker's 215, so that most of a look-alike of about 175 counted as the marker's own).
    fn paler_floor(
        &self,
        frame: &RgbImage,
        state: &MarkerState,
        measured: &Measured,
        window: PixelRect,
        mask: &ChannelRange,
    ) -> Option<u8> {
        if !self.raises_floors() {
            return None;
        }
        let side = window_px(state);
        let core = core_saturation(frame, measured.center, side)?
            .max(core_saturation(frame, window.center(), side).unwrap_or(0.0));
        let paler = paler_part(
            frame,
            &self.region,
            state.reference.threshold,
            measured.holds,
            core,
            side,
        )?;
        Some(floor_between(core, paler, mask))
    }

    /// The saturation floor (8-bit levels) of a colour marker that no paler pixels of its
    /// look raised: [`OWN_FLOOR_SATURATION`] of its core saturation, never below `mask`'s.
    /// A pixel half as saturated as the marker is seldom the marker (a blurred streak under
    /// the floor still counts by its blend with the background, streak weights), but the hue
    /// models weigh it as the marker when its hue is the marker's: a compressed
    /// frame's chroma blocks bleed a red marker's hue into the bark about it, block by block
    /// and frame by frame, and on the combined condition's held-out seed 14000 a marker at rest
    /// on bark was measured 3-5 px off in a quarter of its frames, its blob run on into
    /// such blocks (saturation 100-140 against its core's 225). `None` where floors are not
    /// raised (see [`Tracker::raises_floors`]) or the core is not measured.
    fn own_floor(
        &self,
        frame: &RgbImage,
        state: &MarkerState,
        measured: &Measured,
        mask: &ChannelRange,
    ) -> Option<u8> {
        if !self.raises_floors() {
            return None;
        }
        let core = core_saturation(frame, measured.center, window_px(state))?;
        let floor = (OWN_FLOOR_SATURATION * core).round().clamp(0.0, 255.0) as u8;
        Some(floor.max(mask.lower[1]))
    }

    /// Whether a marker's saturation floor may be raised against paler pixels of its look:
    /// the recovering tracker's hue and hue–saturation models.
    fn raises_floors(&self) -> bool {
        self.config.recovery
            && matches!(
                self.config.model,
                AppearanceModel::Hue { .. } | AppearanceModel::HueSaturation { .. }
            )
    }

    /// The saturation floor (8-bit levels) that keeps the paler pixels of a colour marker's
    /// look elsewhere on the first frame out of its weights: pixels at or above its blob
    /// threshold, away from every marker's window (a window on each side), more than
    /// [`PALER_LEVELS`] under its core saturation, when there are at least
    /// [`BACKGROUND_PALER_MARKERS`] markers' worth of them (bark of a red marker's hue that
    /// it swings onto, where a hue model weighs bark and marker alike and the marker's blob
    /// runs on into the bark). Halfway between the core and their median, never below
    /// `mask`'s. `None` for one-channel and kernel models, where there are too few, and
    /// where their median is not under [`BLUR_KEPT_SATURATION`] of the core (a look-alike
    /// only somewhat paler is told apart by the look-alike masks), or, for an extended
    /// surface of them ([`SURFACE_PALER_MARKERS`] markers' worth or more), under
    /// [`SURFACE_KEPT_SATURATION`]. With no floor, also the
    /// blobs of the marker's look over the whole frame that weighing it found (the marker's
    /// own among them), which [`Tracker::learn_distractors`] would weigh the frame again for.
    fn background_floor(
        &mut self,
        frame: &RgbImage,
        depth: Option<&DepthView<'_>>,
        state: &MarkerState,
        measured: &Measured,
        mask: &ChannelRange,
        inits: &[MarkerInit],
    ) -> (Option<u8>, Option<Vec<Measured>>) {
        if !self.raises_floors() {
            return (None, None);
        }
        let Some(core) = core_saturation(frame, measured.center, window_px(state)) else {
            return (None, None);
        };
        weigh_first_frame(&mut self.region, &self.config, state, frame, depth);
        let away: Vec<PixelRect> = inits
            .iter()
            .map(|i| i.window.grown(i.window.width, i.window.height))
            .collect();
        let limit = core - PALER_LEVELS;
        let threshold = state.reference.threshold;
        let r = &self.region;
        let width = r.rect.width.max(1) as usize;
        let mut paler = Vec::new();
        // Most of the frame is under the threshold: runs of weights without a pixel over it
        // are passed over by a count the compiler vectorises.
        for (c, run) in r.weights.chunks(SCAN_RUN_PX).enumerate() {
            if run.iter().map(|&w| u32::from(w >= threshold)).sum::<u32>() == 0 {
                continue;
            }
            for (j, _) in run.iter().enumerate().filter(|(_, w)| **w >= threshold) {
                let k = c * SCAN_RUN_PX + j;
                let (x, y) = (r.rect.x + (k % width) as i32, r.rect.y + (k / width) as i32);
                if away.iter().any(|a| a.contains(x, y)) {
                    continue;
                }
                let s = saturation(frame.get_pixel(x as u32, y as u32).0);
                if f64::from(s) < limit {
                    paler.push(s);
                }
            }
        }
        let enough =
            paler.len() as f64 >= BACKGROUND_PALER_MARKERS * state.reference.pixels.max(1.0);
        // Only pixels paler than a blurred streak of the marker: a look-alike only somewhat
        // paler is told apart by the look-alike masks.
        let median = enough.then(|| {
            let mid = paler.len() / 2;
            f64::from(*paler.select_nth_unstable(mid).1)
        });
        let surface = paler.len() as f64 >= SURFACE_PALER_MARKERS * state.reference.pixels.max(1.0);
        let kept = if surface {
            SURFACE_KEPT_SATURATION
        } else {
            BLUR_KEPT_SATURATION
        };
        match median {
            Some(median) if median < kept * core => (Some(floor_between(core, median, mask)), None),
            _ => {
                let blobs =
                    candidates_in(&mut self.region, &mut self.labeler, state, &Near::default());
                (None, Some(blobs))
            }
        }
    }

    /// A marker's window must hold pixels and lie entirely inside the frame.
    fn check_window(&self, init: &MarkerInit) -> Result<()> {
        let w = init.window;
        if w.is_empty() {
            return Err(TrackError::EmptyWindow {
                what: format!("of marker {:?}", init.id),
                width: w.width,
                height: w.height,
            });
        }
        if !w.is_inside(&image_rect(self.width, self.height)) {
            return Err(TrackError::WindowOutsideImage {
                what: format!("of marker {:?}", init.id),
                x: w.x,
                y: w.y,
                width: w.width,
                height: w.height,
                image_width: self.width,
                image_height: self.height,
            });
        }
        Ok(())
    }

    /// Every marker-like blob of each marker's appearance on the first frame that is not a
    /// marker: a look-alike from the start. `found[k]`, where given, holds marker `k`'s blobs
    /// over the whole frame already (see [`Tracker::add_marker`]); the others are weighed.
    pub(super) fn learn_distractors(
        &mut self,
        frame: &RgbImage,
        depth: Option<&DepthView<'_>>,
        found: Vec<Option<Vec<Measured>>>,
    ) {
        let centres: Vec<(Point2<f64>, f64)> = self
            .markers
            .iter()
            .map(|m| (m.last_center, window_px(m)))
            .collect();
        for (m, found) in self.markers.iter_mut().zip(found) {
            if m.template.is_some() {
                continue;
            }
            let blobs = found.unwrap_or_else(|| {
                weigh_first_frame(&mut self.region, &self.config, m, frame, depth);
                candidates_in(&mut self.region, &mut self.labeler, m, &Near::default())
            });
            for c in blobs {
                if centres
                    .iter()
                    .all(|(p, side)| (p - c.center).norm() > 0.5 * side)
                {
                    let side = window_px(m);
                    // How pale it is: in a box it is predicted on, the marker's paler
                    // look-alikes are kept out by a saturation floor (`paler_boxes`).
                    let saturation = core_saturation(frame, c.center, side);
                    if let Some(d) = remember_static(m, c.center, c.holds) {
                        d.saturation = saturation;
                    }
                }
            }
        }
        self.share_look_alikes();
    }

    /// Markers of one look share their first frame's look-alikes: a blob one of them takes
    /// for a look-alike is one for the others too, though their own first-frame weights
    /// left it out (a red marker of slightly another hue, for which a reddish-brown disc
    /// fell under the blob threshold on the first frame, took it for itself after a release
    /// and stayed on it for 40 frames: `docs/validation.md`).
    fn share_look_alikes(&mut self) {
        let n = self.markers.len();
        for i in 0..n {
            if self.markers[i].template.is_some() {
                continue;
            }
            let theirs: Vec<(Point2<f64>, PixelRect)> = (0..n)
                .filter(|&k| k != i && same_look(&self.markers[i], &self.markers[k]))
                .flat_map(|k| self.markers[k].distractors.iter())
                .filter(|d| !d.shared)
                .map(|d| (d.at, d.bounds))
                .collect();
            let m = &mut self.markers[i];
            let near = (DISTRACTOR_RADIUS * window_px(m)).max(2.0);
            for (at, bounds) in theirs {
                // One it knows already stays as its own.
                if m.distractors.iter().all(|o| (o.at - at).norm() >= near)
                    && let Some(d) = remember_static(m, at, bounds)
                {
                    d.shared = true;
                }
            }
        }
    }
}

/// Remember a look-alike of the first frame at `at` as static from the start (seen twice);
/// the entry kept, to be told more about it.
fn remember_static(
    m: &mut MarkerState,
    at: Point2<f64>,
    bounds: PixelRect,
) -> Option<&mut Distractor> {
    let side = window_px(m);
    remember_distractor(m, at, bounds, side, 0);
    remember_distractor(m, at, bounds, side, 0);
    m.distractors.iter_mut().find(|d| d.at == at)
}

/// Weigh marker `m`'s look over the whole first `frame` into `region` (no previous frame,
/// nothing masked), sparsely: the background floor and the first look-alikes need only the
/// blobs and the pixels over the blob threshold, which a sparse fill gives as a full one does.
fn weigh_first_frame(
    region: &mut Region,
    config: &TrackerConfig,
    m: &MarkerState,
    frame: &RgbImage,
    depth: Option<&DepthView<'_>>,
) {
    let whole = image_rect(frame.width(), frame.height());
    fill(region, config, m, frame, None, depth, whole, &[], &[], true);
}

/// Weights passed over together by the background floor's scan when none reaches the blob
/// threshold.
const SCAN_RUN_PX: usize = 64;

/// A raised saturation floor: halfway between a marker's core saturation and the paler
/// pixels' (8-bit levels), never below `mask`'s.
fn floor_between(core: f64, paler: f64, mask: &ChannelRange) -> u8 {
    let floor = (0.5 * (core + paler)).round().clamp(0.0, 255.0) as u8;
    floor.max(mask.lower[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A red disc of radius 6 px at (40, 32) on grey, with a barely darker red disc of
    /// the same size touching it at (`beside_x`, 32), and the marker's first window on the
    /// red one.
    fn marker_beside(beside_x: u32) -> Result<Tracker> {
        let frame = RgbImage::from_fn(112, 64, |x, y| {
            let on = |cx: u32| {
                let (dx, dy) = (f64::from(x) - f64::from(cx), f64::from(y) - 32.0);
                dx * dx + dy * dy <= 36.0
            };
            if on(40) {
                image::Rgb([215, 25, 30])
            } else if on(beside_x) {
                image::Rgb([205, 28, 32])
            } else {
                image::Rgb([100, 110, 95])
            }
        });
        let init = MarkerInit {
            id: "A".into(),
            window: PixelRect::new(33, 25, 15, 15),
        };
        Tracker::new(TrackerConfig::default(), &frame, None, &[init])
    }

    #[test]
    fn a_look_alike_touching_the_first_window_is_not_learnt_as_the_marker() -> Result<()> {
        let truth = Point2::new(40.0, 32.0);
        // Apart, the marker's blob is its own (113 pixels).
        let apart = marker_beside(80)?;
        let alone = apart.markers[0].reference.pixels;
        assert!((90.0..=140.0).contains(&alone), "{alone}");
        // Touching: the merged blob's centre would be 3 px toward the other disc, and its
        // pixels twice the marker's; the first frame's centre and blob are the window's.
        let t = marker_beside(52)?;
        let center = t.tracks[0].observations[0]
            .center
            .unwrap_or(Point2::origin());
        assert!((center - truth).norm() < 2.5, "{center}");
        let pixels = t.markers[0].reference.pixels;
        assert!(pixels <= 1.3 * alone, "{pixels} against {alone}");
        Ok(())
    }

    /// A red marker's pixel at `(x, y)`: red on both sides of hue 0 (179 and 1) in a
    /// checkerboard, as a real red marker is.
    fn red_marker(x: u32, y: u32) -> image::Rgb<u8> {
        if (x + y).is_multiple_of(2) {
            image::Rgb([215, 25, 30])
        } else {
            image::Rgb([215, 30, 25])
        }
    }

    /// A red disc of radius 7 px at (`marker_x`, 32) on grey, in front of a reddish-brown
    /// one of radius 8 at (45, 37) (saturation about 180 against the red's 225; hue 4, in a
    /// bin of the red's), which it half covers when it is at 40.
    fn red_beside_brown(marker_x: f64) -> RgbImage {
        red_before(marker_x, [150, 60, 45], Point2::new(45.0, 37.0), 8.0)
    }

    /// A red disc of radius 7 px at (`marker_x`, 32) on grey, in front of a disc of colour
    /// `look` and radius `radius` at `at`.
    fn red_before(marker_x: f64, look: [u8; 3], at: Point2<f64>, radius: f64) -> RgbImage {
        RgbImage::from_fn(112, 64, |x, y| {
            let d2 = |cx: f64, cy: f64, r: f64| {
                let (dx, dy) = (f64::from(x) - cx, f64::from(y) - cy);
                dx * dx + dy * dy <= r * r
            };
            if d2(marker_x, 32.0, 7.0) {
                red_marker(x, y)
            } else if d2(at.x, at.y, radius) {
                image::Rgb(look)
            } else {
                image::Rgb([100, 110, 95])
            }
        })
    }

    /// Marker "A" learnt from its first `window` on `frame`.
    fn marker_a(frame: &RgbImage, window: PixelRect) -> Result<Tracker> {
        let init = MarkerInit {
            id: "A".into(),
            window,
        };
        Tracker::new(TrackerConfig::default(), frame, None, &[init])
    }

    /// The red disc of `frame_at(x)` starts on itself at x = 40 and, pulled 3 px a frame
    /// away from what touches it for 6 frames, is followed, not left on the look-alike.
    fn follows_the_pull(t: &mut Tracker, frame_at: impl Fn(f64) -> RgbImage) -> Result<()> {
        let start = t.tracks[0].observations[0]
            .center
            .unwrap_or(Point2::origin());
        assert!((start - Point2::new(40.0, 32.0)).norm() < 1.0, "{start}");
        for step in 1..=6 {
            t.update(&frame_at(40.0 - 3.0 * f64::from(step)), None)?;
        }
        let last = t.tracks[0].observations[6];
        let end = last.center.unwrap_or(Point2::origin());
        assert!((end - Point2::new(22.0, 32.0)).norm() < 1.5, "{end}");
        assert_eq!(last.status, TrackStatus::Tracked);
        Ok(())
    }

    #[test]
    fn a_paler_look_alike_touching_the_marker_is_kept_out_of_it() -> Result<()> {
        let mut t = marker_a(&red_beside_brown(40.0), PixelRect::new(32, 24, 17, 17))?;
        // Its blob is the red disc's (about 150 pixels), not the pair's.
        let pixels = t.markers[0].reference.pixels;
        assert!((120.0..=190.0).contains(&pixels), "{pixels}");
        follows_the_pull(&mut t, red_beside_brown)
    }

    /// A look-alike only about 30 levels paler than the marker (saturation 193 against
    /// 225, hue 3: the stress scenes' reddish-brown distractors are 178–187 against 200–230),
    /// mostly hidden behind the marker on the first frame: learnt as one blob with it, the
    /// marker would start 2 px toward it and stay on it when pulled away.
    #[test]
    fn a_slightly_paler_look_alike_behind_the_marker_is_kept_out_of_it() -> Result<()> {
        let frame_at = |x| red_before(x, [185, 60, 45], Point2::new(44.0, 36.0), 7.0);
        let mut t = marker_a(&frame_at(40.0), PixelRect::new(33, 25, 15, 15))?;
        follows_the_pull(&mut t, frame_at)
    }

    /// A reddish-brown look-alike (saturation 178 against the red's 225, hue 4, in a bin of
    /// the red's) seen apart from the marker on the first frame, which the marker then
    /// passes over: in its box only pixels more saturated than halfway between the two
    /// count, so the marker is measured on itself all the way, not refused as the pair (a
    /// blob centred between the two, on the look-alike) for the frames it overlaps it.
    #[test]
    fn a_marker_passing_over_a_paler_look_alike_is_measured_on_itself() -> Result<()> {
        let (look, at) = ([150, 60, 45], Point2::new(62.0, 35.0));
        let mut t = marker_a(
            &red_before(24.0, look, at, 9.0),
            PixelRect::new(17, 25, 15, 15),
        )?;
        // 4 px a frame, over the quarter window a frame of a marker at rest: passing.
        let path: Vec<f64> = (1..=16).map(|k| 24.0 + 4.0 * f64::from(k)).collect();
        follows_the_path(&mut t, &path, 32.0, 1.5, |x| red_before(x, look, at, 9.0))
    }

    /// Marker 0 of `t`, moved along x through `path` at height `y` (`frame_at(x)`), is
    /// `tracked` within `tolerance_px` of the marker on every frame.
    fn follows_the_path(
        t: &mut Tracker,
        path: &[f64],
        y: f64,
        tolerance_px: f64,
        frame_at: impl Fn(f64) -> RgbImage,
    ) -> Result<()> {
        for &x in path {
            t.update(&frame_at(x), None)?;
        }
        for (k, &x) in path.iter().enumerate() {
            let o = t.tracks[0].observations[k + 1];
            let c = o.center.unwrap_or(Point2::origin());
            assert!(
                (c - Point2::new(x, y)).norm() < tolerance_px && o.status == TrackStatus::Tracked,
                "frame {}: {c} {:?} for ({x}, {y})",
                k + 1,
                o.status
            );
        }
        Ok(())
    }

    /// A red disc of radius 7 px at (`marker_x`, 40) on grey in front of bark of the red's
    /// hue over the columns `bark` holds, in `colours` (the first on every fifth column, a
    /// darker streak; the second elsewhere).
    fn red_over(marker_x: f64, bark: impl Fn(u32) -> bool, colours: [[u8; 3]; 2]) -> RgbImage {
        RgbImage::from_fn(176, 80, |x, y| {
            let (dx, dy) = (f64::from(x) - marker_x, f64::from(y) - 40.0);
            if dx * dx + dy * dy <= 49.0 {
                red_marker(x, y)
            } else if bark(x) {
                image::Rgb(colours[usize::from(x % 5 != 0)])
            } else {
                image::Rgb([100, 110, 95])
            }
        })
    }

    /// [`red_over`] a band of bark (hue 178, saturation about 90 against the red's 225) over
    /// x 90..130, as reddish bark beside a red marker.
    fn red_over_bark(marker_x: f64) -> RgbImage {
        red_over(
            marker_x,
            |x| (90..130).contains(&x),
            [[120, 76, 78], [150, 95, 98]],
        )
    }

    /// [`red_over`] bark only about a third paler than the marker (saturation 153 against
    /// 225, hue 179: as pale as the marker's own streak at a release), over x 80..176 and the
    /// whole height: an extended surface, 30 markers' worth of it.
    fn red_over_pale_bark(marker_x: f64) -> RgbImage {
        red_over(marker_x, |x| x >= 80, [[130, 52, 54], [160, 64, 66]])
    }

    #[test]
    fn a_marker_swung_onto_a_surface_of_its_hue_a_third_paler_is_measured_on_itself() -> Result<()>
    {
        let mut t = marker_a(&red_over_pale_bark(40.0), PixelRect::new(32, 32, 17, 17))?;
        // Onto the surface and 50 px into it, 4 px a frame: without a raised floor the
        // marker's blob would be the whole surface.
        let path: Vec<f64> = (1..=22).map(|k| 40.0 + 4.0 * f64::from(k)).collect();
        follows_the_path(&mut t, &path, 40.0, 1.0, red_over_pale_bark)
    }

    /// [`red_over`] bark a quarter paler than the marker (saturation 170 against 225, 0.76
    /// of it; the third generator's tuning seeds 36 and 37 have bark at 0.73 of their
    /// markers' cores) over the surface of [`red_over_pale_bark`].
    fn red_over_bark_a_quarter_paler(marker_x: f64) -> RgbImage {
        red_over(marker_x, |x| x >= 80, [[120, 40, 42], [150, 50, 52]])
    }

    #[test]
    fn a_marker_swung_onto_a_surface_of_its_hue_a_quarter_paler_is_measured_on_itself() -> Result<()>
    {
        let mut t = marker_a(
            &red_over_bark_a_quarter_paler(40.0),
            PixelRect::new(32, 32, 17, 17),
        )?;
        let path: Vec<f64> = (1..=22).map(|k| 40.0 + 4.0 * f64::from(k)).collect();
        follows_the_path(&mut t, &path, 40.0, 1.0, red_over_bark_a_quarter_paler)
    }

    #[test]
    fn a_marker_swung_onto_bark_of_its_hue_is_measured_on_itself() -> Result<()> {
        let mut t = marker_a(&red_over_bark(40.0), PixelRect::new(32, 32, 17, 17))?;
        // Onto the bark and across it, 4 px a frame: on the bark the hue model weighs the
        // bark as the marker, and the marker's blob would be the whole band.
        let path: Vec<f64> = (1..=20).map(|k| 40.0 + 4.0 * f64::from(k)).collect();
        follows_the_path(&mut t, &path, 40.0, 1.0, red_over_bark)
    }

    /// A red disc of radius 7 px at (40, 32) on grey and, with `bleed`, a block of 8x8
    /// pixels at its upper right of the red's hue at under half its saturation (102 against
    /// 225: a compressed frame's chroma block bled from the marker into what is about it).
    fn red_with_bleed(bleed: bool) -> RgbImage {
        RgbImage::from_fn(112, 64, |x, y| {
            let (dx, dy) = (f64::from(x) - 40.0, f64::from(y) - 32.0);
            if dx * dx + dy * dy <= 49.0 {
                red_marker(x, y)
            } else if bleed && (44..52).contains(&x) && (22..30).contains(&y) {
                image::Rgb([150, 100, 90])
            } else {
                image::Rgb([100, 110, 95])
            }
        })
    }

    #[test]
    fn a_block_of_the_markers_hue_far_paler_than_it_is_not_weighed_as_the_marker() -> Result<()> {
        let mut t = marker_a(&red_with_bleed(false), PixelRect::new(33, 25, 15, 15))?;
        // Nothing paler of its look on the first frame: its own floor, half its core's.
        let core =
            core_saturation(&red_with_bleed(false), Point2::new(40.0, 32.0), 15.0).expect("a core");
        let floor = (OWN_FLOOR_SATURATION * core).round() as u8;
        assert!(floor > 102, "{floor}");
        // The block appears beside the marker at rest and stays (its first frame is a
        // change a streak could explain; the frames after it are not).
        for _ in 0..4 {
            t.update(&red_with_bleed(true), None)?;
        }
        for o in &t.tracks[0].observations[2..] {
            let c = o.center.unwrap_or(Point2::origin());
            // Weighed as the marker, the block (about 50 pixels beside the disc's 150)
            // would pull the centre 2-3 px up and right.
            assert!((c - Point2::new(40.0, 32.0)).norm() < 1.0, "{c}");
            assert_eq!(o.status, TrackStatus::Tracked);
        }
        Ok(())
    }
}
