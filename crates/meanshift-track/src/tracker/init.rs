//! Starting to track: a marker's appearance learnt from its first window, and the
//! look-alikes already in the first frame.

use super::*;

impl Tracker {
    #[allow(clippy::too_many_lines)] // longer than 100 lines; to be split by concept (issue 21)
    pub(super) fn add_marker(
        &mut self,
        frame: &RgbImage,
        depth: Option<&DepthView<'_>>,
        init: &MarkerInit,
    ) -> Result<()> {
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
        let lookup = Lookup::new(&config.model, &model, &mask);
        let center = w.center();
        let side = f64::from(w.width.max(w.height));
        let mut state = MarkerState {
            id: init.id.clone(),
            model,
            lookup,
            init_size: (w.width, w.height),
            size: (w.width, w.height),
            filter: Kalman::new(center, MEASUREMENT_PX, 0.1 * side),
            swing: Swing::default(),
            acceleration_px: ACCELERATION_MIN_PX,
            last_center: center,
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
            last_status: TrackStatus::Tracked,
            context: None,
            context_level: 1.0,
            context_var: 0.0,
            confidence_mean: 1.0,
            confidence_var: 0.0,
            gate_var: 1.0,
            distractors: Vec::new(),
            colour: [0.0; 3],
            template: None,
        };
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
        );
        state.reference.mass = self.region.mass(w).max(1.0);
        learn_blob(&mut state, &self.region, &mut self.labeler, w);
        state.reference.gap = state.reference.gap.max(hole_gap(frame, w));
        state.colour = mean_colour(frame, &self.region, w, state.reference.threshold);
        let mode = self.region.locate(
            &state.model,
            &config.criteria,
            state.reference.mass,
            center,
            state.size,
        );
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
            candidates_in(&mut self.region, &mut self.labeler, &state, None, &[])
                .into_iter()
                .filter(|c| c.holds.intersect(&w).area() > 0)
                .min_by(|a, b| near(a).total_cmp(&near(b)))
                .unwrap_or_else(|| plain(&self.region, mode))
        } else {
            plain(&self.region, mode)
        };
        let observation = Observation {
            center: Some(measured.center),
            window: measured.window,
            status: TrackStatus::Tracked,
            confidence: measured.confidence,
        };
        state.last_center = measured.center;
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
        Ok(())
    }

    /// Every marker-like blob of each marker's appearance on the first frame that is not a
    /// marker: a look-alike from the start.
    pub(super) fn learn_distractors(&mut self, frame: &RgbImage, depth: Option<&DepthView<'_>>) {
        let centres: Vec<(Point2<f64>, f64)> = self
            .markers
            .iter()
            .map(|m| (m.last_center, window_px(m)))
            .collect();
        let whole = image_rect(self.width, self.height);
        for m in &mut self.markers {
            if m.template.is_some() {
                continue;
            }
            fill(
                &mut self.region,
                &self.config,
                m,
                frame,
                None,
                depth,
                whole,
                &[],
            );
            for c in candidates_in(&mut self.region, &mut self.labeler, m, None, &[]) {
                if centres
                    .iter()
                    .all(|(p, side)| (p - c.center).norm() > 0.5 * side)
                {
                    let side = window_px(m);
                    remember_distractor(m, c.center, c.holds, side);
                    remember_distractor(m, c.center, c.holds, side);
                }
            }
        }
    }
}
