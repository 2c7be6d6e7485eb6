//! One step of the pose: each branch's oscillator advanced under its force, the branch bent
//! by its displacement, and its segments composed on its parent's (two branches at once
//! where the second does not hang on the first).

use super::*;

impl Simulation {
    pub(super) fn integrate(&mut self) {
        self.pose.time_s += self.dt_s;
        self.advance_pose(true);
    }

    pub(super) fn update_pose(&mut self) {
        self.advance_pose(false);
    }

    /// One pass over the branches, parents first: with `integrate`, advance each oscillator
    /// under its rest-frame force; then bend the branch and compose its pose on its
    /// parent's (already updated) one.
    pub(super) fn advance_pose(&mut self, integrate: bool) {
        let magnitude = self.config.forcing == Forcing::Magnitude;
        let nb = self.branches.len();
        let mut i = 0;
        while i < nb {
            // Two branches at once (every operation on a pair of lanes) when the second does
            // not hang on the first.
            let pair = i + 1 < nb && self.pairable[i];
            let (xa, sa) = self.oscillate(i, integrate, magnitude);
            if pair {
                let (xb, sb) = self.oscillate(i + 1, integrate, magnitude);
                self.bend_pair(i, [xa, xb], [sa, sb]);
                i += 2;
            } else {
                self.bend(i, &xa, sa);
                i += 1;
            }
        }
    }

    /// Advance branch `i`'s oscillator (with `integrate`), record its angle and
    /// displacement; its displacement vector and bending scale 1/δ(x̂).
    #[inline(always)]
    pub(super) fn oscillate(
        &mut self,
        i: usize,
        integrate: bool,
        magnitude: bool,
    ) -> (Vector3<f64>, f64) {
        let b = &mut self.branches[i];
        if integrate {
            let f = self.forces[i];
            let (fu, fw) = (f.dot(&b.u), f.dot(&b.w));
            if magnitude {
                let m = (fu * fu + fw * fw).sqrt();
                if m > 0.0 {
                    b.dir = [fu / m, fw / m];
                }
                (b.xs, b.vs) = b.step.apply(b.xs, b.vs, m * b.inv_mass_per_kg);
                b.x = [b.xs * b.dir[0], b.xs * b.dir[1]];
            } else {
                for (c, fc) in [fu, fw].into_iter().enumerate() {
                    (b.x[c], b.vel[c]) = b.step.apply(b.x[c], b.vel[c], fc * b.inv_mass_per_kg);
                }
            }
        }
        let [xu, xw] = b.x;
        // 1/δ(x̂) with x̂ = x/|x|, as |x|² / xᵀKx (no square root needed).
        let quad = xu * xu * b.k[0][0] + 2.0 * xu * xw * b.k[0][1] + xw * xw * b.k[1][1];
        let scale = if quad > 0.0 {
            (xu * xu + xw * xw) / quad
        } else {
            0.0
        };
        self.pose.angle_rad[i] = (xu * b.angle_uw[0] + xw * b.angle_uw[1]) * scale;
        self.pose.displacement_m[i] = b.x;
        (b.u * xu + b.w * xw, scale)
    }

    /// Bend branch `i` by displacement `x` (bending scale `scale`), compose its frames on
    /// its attachment and hand its children theirs.
    #[inline(always)]
    pub(super) fn bend(&mut self, i: usize, x: &Vector3<f64>, scale: f64) {
        let Attach {
            rotation: mut g,
            mut start,
        } = self.attach[i];
        start += g * self.branches[i].base_offset;
        let first = i * SEGMENTS;
        let mut frames = [Attach::default(); SEGMENTS];
        for (j, frame) in frames.iter_mut().enumerate() {
            let seg = &self.segments[first + j];
            let q = rotation(&(seg.lever.cross(x) * scale));
            g *= q;
            let a = g * seg.dir;
            self.pose.local[first + j] = q;
            self.dir[first + j] = a;
            *frame = Attach { rotation: g, start };
            start += a * seg.length_m;
        }
        for &(j, c) in &self.children[self.children_at[i]..self.children_at[i + 1]] {
            self.attach[c] = frames[j];
        }
    }

    /// [`Self::bend`] for branches `i` and `i + 1` together, lane by lane.
    #[inline(always)]
    pub(super) fn bend_pair(&mut self, i: usize, x: [Vector3<f64>; 2], scale: [f64; 2]) {
        let lanes = [i, i + 1];
        let mut g = [[0.0; 2]; 4];
        let mut start = [[0.0; 2]; 3];
        for (l, &bi) in lanes.iter().enumerate() {
            let at = self.attach[bi];
            let p = at.start + at.rotation * self.branches[bi].base_offset;
            let q = at.rotation;
            for (c, v) in [q.w, q.i, q.j, q.k].into_iter().enumerate() {
                g[c][l] = v;
            }
            for c in 0..3 {
                start[c][l] = p[c];
            }
        }
        let xs = [0, 1, 2].map(|c| [x[0][c] * scale[0], x[1][c] * scale[1]]);
        let mut frames = [[Attach::default(); SEGMENTS]; 2];
        let (segs_a, segs_b) = self.segments[i * SEGMENTS..(i + 2) * SEGMENTS].split_at(SEGMENTS);
        for (j, (sa, sb)) in segs_a.iter().zip(segs_b).enumerate() {
            let lev = [0, 1, 2].map(|c| [sa.lever[c], sb.lever[c]]);
            let phi = cross2(&lev, &xs);
            let q = rotation2(&phi);
            g = qmul2(&g, &q);
            let d = [0, 1, 2].map(|c| [sa.dir[c], sb.dir[c]]);
            let a = rotate2(&g, &d);
            let len = [sa.length_m, sb.length_m];
            for (l, &bi) in lanes.iter().enumerate() {
                let s = bi * SEGMENTS + j;
                self.pose.local[s] = UnitQuaternion::new_unchecked(Quaternion::new(
                    q[0][l], q[1][l], q[2][l], q[3][l],
                ));
                self.dir[s] = Vector3::new(a[0][l], a[1][l], a[2][l]);
                frames[l][j] = Attach {
                    rotation: UnitQuaternion::new_unchecked(Quaternion::new(
                        g[0][l], g[1][l], g[2][l], g[3][l],
                    )),
                    start: Point3::new(start[0][l], start[1][l], start[2][l]),
                };
            }
            for c in 0..3 {
                for l in 0..2 {
                    start[c][l] += a[c][l] * len[l];
                }
            }
        }
        for (l, &bi) in lanes.iter().enumerate() {
            for &(j, c) in &self.children[self.children_at[bi]..self.children_at[bi + 1]] {
                self.attach[c] = frames[l][j];
            }
        }
    }
}
