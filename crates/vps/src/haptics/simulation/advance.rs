//! Step 3 of the loop: the motion by conservative advancement on the distance field, in
//! sub-steps no point moves more than a quarter voxel in, stopped where the deepest point
//! would pass the allowed depth, then slid along the contact and, pressed, lifted off it
//! (the module docs of [`super`]).

use super::*;

/// Sub-steps of an advancement move no point by more than this many voxels.
const SUBSTEP_VOXELS: f64 = 0.25;
/// At most this many sub-steps per step: faster motion is slowed to it (a speed limit of
/// `MAX_SUBSTEPS · SUBSTEP_VOXELS` voxels per step, reported as `limited`).
const MAX_SUBSTEPS: u32 = 64;
/// Searches in a sub-step that went too deep, at most. Each shrinks the bracket to 90 % of it
/// or less; when they run out first, the object stops at the deepest pose found within the
/// allowed depth (short of it, never past it).
const BISECTIONS: u32 = 8;

/// When at least this many sub-steps are left, the first of them too deep is found by one
/// swept walk ([`sweep`]) rather than a query each. The walk grows every sphere
/// by the motion, so it costs several queries: on the built-in pair it saved time from about
/// eight sub-steps on and lost some at four or five (`docs/PERFORMANCE.md`).
const SWEEP_MIN_SUBSTEPS: u32 = 6;
/// The search stops at a pose this deep, as a fraction of the allowed depth, or deeper.
const CLOSE_ENOUGH: f64 = 0.9;
/// A blocked slide is lifted off the face by this many times the depth it would gain, so
/// that it ends a little shallower than it started: more lift costs more work against the
/// coupling's pressing (1.5 left 7 of the pressed test's 349 steps stuck for passivity, 1.1
/// left 2).
const LIFT_PER_GAIN: f64 = 1.1;
/// A blocked slide is lifted by at most this much per unit of its length (5.7°): the stored
/// distances are rounded to 1/32 voxel, so the interpolated field's gradient may lean from
/// the true one by about that much per voxel (1.8° along an axis, 3.1° across a cell's
/// diagonal); a steeper rise is a real step in the face, which the object must not climb.
const MAX_LIFT_SLOPE: f64 = 0.1;
/// A lifted slide that would leave the step with more energy than passivity allows is tried
/// once more shortened, if to no less than this fraction of it.
const MIN_SHORTER_SLIDE: f64 = 0.5;
/// A step's queries go to the thread pool only after a query that tested this many points or
/// more. A pressed contact of the loop tests far fewer than a deep one (about 10,000 points of
/// the built-in 10⁶-point shell, 2,200 of the 10⁵ one), and handing so little to the pool cost
/// more in its tail than it saved: waking a busy core's thread can take a 4 ms scheduler tick
/// (`docs/PERFORMANCE.md`, "The loop's queries on the calling thread").
const LOOP_PARALLEL_MIN_TESTED: u64 = 16_384;

impl<S: PointshellData + ?Sized> Simulation<'_, S> {
    /// Move the object by `shift` (of its centre of mass) and `turn` (a rotation vector about
    /// it) as far as the allowed depth and the time budget (counted from `started`) let it;
    /// `ledger` is the step's energy balance, for the lifted slide.
    pub(super) fn advance(
        &self,
        ledger: &Ledger,
        shift: DVec3,
        turn: DVec3,
        started: Instant,
    ) -> Result<Advance, HapticsError> {
        let deadline = self.params.step_budget.map(|b| started + b);
        let first = self.advance_from(&self.state.pose, self.contact, shift, turn, deadline)?;
        if first.fraction >= 1.0 || first.out_of_time {
            return Ok(first);
        }
        // Blocked: slide. The rest of the motion, without its part along the contact force
        // (the wall's normal there) and about the contact torque (about the centre of mass).
        let rest = 1.0 - first.fraction;
        let shift = not_into(shift * rest, first.contact.force);
        let turn = not_into(turn * rest, self.contact_torque(&first.pose, &first.contact));
        let mut slid = self.advance_from(&first.pose, first.contact, shift, turn, deadline)?;
        if slid.fraction < 1.0 && !slid.out_of_time {
            let rest = 1.0 - slid.fraction;
            let (lifted, queries) = self.lifted_slide(ledger, &slid, shift * rest, turn * rest, deadline)?;
            slid.queries += queries;
            if let Some(lifted) = lifted {
                slid = Advance {
                    queries: slid.queries,
                    ..lifted
                };
            }
        }
        Ok(Advance {
            queries: first.queries + slid.queries,
            fraction: first.fraction,
            ..slid
        })
    }

    /// A slide blocked at `from` although it runs across the contact force. Pressed to the
    /// allowed depth, the object has no room for the lean of the face as the distance field
    /// sees it from the face the points' normals see: the stored distances are rounded to
    /// 1/32 voxel, so the interpolated field's gradient leans from the true one by up to about
    /// 1/32 per voxel, and a slide across the contact force may go deeper at 2–3 % of its
    /// length. So the rest of the slide (`shift`, `turn`) is tried once more lifted along the
    /// contact force by [`LIFT_PER_GAIN`] times the depth it would gain, when that is a small
    /// slope of the slide ([`MAX_LIFT_SLOPE`]: a real step in the face still stops the
    /// object), and kept only if the step stays passive by `ledger`: the object's energy
    /// after it no more than before plus the device's work; a slide that would keep too much
    /// kinetic energy for that is tried once more shortened. Also the queries it ran.
    fn lifted_slide(
        &self,
        ledger: &Ledger,
        from: &Advance,
        shift: DVec3,
        turn: DVec3,
        deadline: Option<Instant>,
    ) -> Result<(Option<Advance>, u32), HapticsError> {
        let normal = from.contact.force.normalize_or_zero();
        let reach = shift.length() + turn.length() * self.radius;
        if normal == DVec3::ZERO || reach == 0.0 {
            return Ok((None, 0));
        }
        // The depth at the slide's end: known when the blocked slide found it too deep there,
        // at the same pose (it made no progress, so `shift` and `turn` are its own). When the
        // pressed point alone proved that, the gain is first taken as that point's, the one at
        // the allowed depth, and the pose is queried only if that lift leaves the slide
        // blocked (the pressed slide's steps of three queries were the 10⁵-point run's tail).
        // So a slide may be kept lifted by the point's gain where the pose's, larger, would
        // have been too steep: it still made progress within the allowed depth.
        let end_pose = self.moved(&from.pose, shift, turn, 1.0)?;
        let (mut at_end, mut queries) = match from.too_deep_at {
            Some(t) if t.fraction == 1.0 && from.fraction == 0.0 => (t, 0),
            _ => match self.checked(&end_pose, deadline)? {
                Some(c) => (TooDeepPose::queried(1.0, c.max_penetration), 1),
                None => return Ok((None, 1)),
            },
        };
        let (lifted_shift, lifted) = loop {
            let gain = at_end.depth - from.contact.max_penetration;
            let lift = LIFT_PER_GAIN * gain;
            // Unqueried, the depth is a lower bound: a lift too steep for it is too steep for
            // the pose's own depth too, but no gain from it proves nothing.
            if lift > MAX_LIFT_SLOPE * reach || (gain <= 0.0 && at_end.queried) {
                return Ok((None, queries));
            }
            if gain > 0.0 {
                let lifted_shift = shift + normal * lift;
                let lifted = self.advance_from(&from.pose, from.contact, lifted_shift, turn, deadline)?;
                queries += lifted.queries;
                if lifted.fraction > 0.0 && !lifted.out_of_time {
                    break (lifted_shift, lifted);
                }
                if lifted.out_of_time || at_end.queried {
                    return Ok((None, queries));
                }
            }
            // The point's gain was not enough (or none): the pose's own, once, if it is more.
            queries += 1;
            match self.checked(&end_pose, deadline)? {
                Some(c) if c.max_penetration > at_end.depth => {
                    at_end = TooDeepPose::queried(1.0, c.max_penetration);
                }
                _ => return Ok((None, queries)),
            }
        };
        let excess = ledger.excess(self, &lifted);
        if excess <= 0.0 {
            return Ok((Some(lifted), queries));
        }
        // The slide would keep more kinetic energy than the step may have: shorten it by what
        // that takes, were the kinetic energy all there is (it mostly is: the springs and the
        // contact change little along a slide), and try once more.
        let kinetic = self.kinetic_energy(&self.stopped_at(&lifted));
        let shorter = (1.0 - 2.0 * excess / kinetic).max(0.0).sqrt();
        if shorter < MIN_SHORTER_SLIDE {
            return Ok((None, queries));
        }
        let lifted = self.advance_from(
            &from.pose,
            from.contact,
            lifted_shift * shorter,
            turn * shorter,
            deadline,
        )?;
        queries += lifted.queries;
        let kept = lifted.fraction > 0.0 && !lifted.out_of_time && ledger.excess(self, &lifted) <= 0.0;
        Ok((kept.then_some(lifted), queries))
    }

    /// `from` moved by `fraction` of `shift` (of the centre of mass) and `turn` (about it).
    pub(super) fn moved(&self, from: &Pose, shift: DVec3, turn: DVec3, fraction: f64) -> Result<Pose, HapticsError> {
        let rotation = (DQuat::from_scaled_axis(turn * fraction) * from.rotation).normalize();
        let c = self.centre_at(from) + shift * fraction;
        let translation = c - rotation * self.body.centre;
        let q = [rotation.w, rotation.x, rotation.y, rotation.z];
        Ok(Pose::new(translation.to_array(), q)?)
    }

    /// The contact at `pose`: on the calling thread unless the last query was a large one
    /// ([`LOOP_PARALLEL_MIN_TESTED`]). The same bits either way.
    fn query(&self, pose: &Pose, params: &ContactParams) -> Result<Contact, HapticsError> {
        let large = self.last_points_tested.load(Ordering::Relaxed) >= LOOP_PARALLEL_MIN_TESTED;
        let parallel_min_points = if large { PARALLEL_MIN_POINTS } else { u64::MAX };
        let c = contact_threaded(self.voxmap, self.shell, pose, params, parallel_min_points)?;
        self.last_points_tested.store(c.points_tested, Ordering::Relaxed);
        Ok(c)
    }

    /// The contact at `pose`, or `None` when the time to `deadline` ran out before a complete
    /// answer (an incomplete one does not bound the deepest point).
    pub(super) fn checked(&self, pose: &Pose, deadline: Option<Instant>) -> Result<Option<Contact>, HapticsError> {
        let Some(deadline) = deadline else {
            return self.query(pose, &self.params.contact).map(Some);
        };
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Ok(None);
        }
        let params = ContactParams {
            budget: Some(left),
            ..self.params.contact
        };
        let c = self.query(pose, &params)?;
        Ok(c.complete.then_some(c))
    }

    /// Conservative advancement from `from` (with its contact `at_start`): the pose at the
    /// largest fraction of the motion found with every point within the allowed depth, in
    /// the time to `deadline`.
    fn advance_from(
        &self,
        from: &Pose,
        at_start: Contact,
        shift: DVec3,
        turn: DVec3,
        deadline: Option<Instant>,
    ) -> Result<Advance, HapticsError> {
        let limit = self.params.max_penetration * self.voxel;
        let reach = shift.length() + turn.length() * self.radius;
        let wanted = (reach / (SUBSTEP_VOXELS * self.voxel)).ceil();
        // Too fast: slowed to the speed limit.
        let (n, scale) = if wanted > MAX_SUBSTEPS as f64 {
            (MAX_SUBSTEPS, MAX_SUBSTEPS as f64 / wanted)
        } else {
            (wanted.max(1.0) as u32, 1.0)
        };
        let at = |fraction: f64| self.moved(from, shift, turn, fraction * scale);
        let mut done = Advance {
            pose: *from,
            contact: at_start,
            fraction: 0.0,
            queries: 0,
            out_of_time: false,
            too_deep_at: None,
        };
        let mut known_too_deep = None;
        // Out of contact, the sweep starts at the first sub-step; in contact, that one is
        // queried alone first (held against a wall, it is the one too deep).
        let sweep_from = if at_start.points_in_contact == 0 { 1 } else { 2 };
        let mut j = 0;
        while j < n {
            j += 1;
            // Without a time budget and with enough sub-steps left, the first one too deep and
            // its depth come from one swept walk: the same answers as querying each in turn.
            // Only the sub-step before it is then queried, for its contact; and when none is
            // too deep and nothing touches at the end, the contact there is zero, unqueried.
            if j == sweep_from && n + 1 - j >= SWEEP_MIN_SUBSTEPS && deadline.is_none() {
                let poses = (j..=n)
                    .map(|i| at(i as f64 / n as f64))
                    .collect::<Result<Vec<_>, _>>()?;
                done.queries += 1;
                let swept = sweep(self.voxmap, self.shell, &poses, &self.params.contact, limit)?;
                match swept.too_deep {
                    None if !swept.touching_at_end => {
                        let untouched = Contact {
                            complete: true,
                            ..Contact::default()
                        };
                        (done.pose, done.contact, done.fraction) = (poses[poses.len() - 1], untouched, scale);
                        return Ok(done);
                    }
                    // Every sub-step within the limit: the loop queries the last one.
                    None => j = n,
                    Some(stop) => {
                        j += stop.pose as u32;
                        known_too_deep = Some(stop.max_penetration);
                        if stop.pose > 0 {
                            let pose = poses[stop.pose - 1];
                            done.queries += 1;
                            let c = self.query(&pose, &self.params.contact)?;
                            (done.pose, done.contact, done.fraction) = (pose, c, (j - 1) as f64 / n as f64 * scale);
                        }
                    }
                }
            }
            let (lo, hi) = ((j - 1) as f64 / n as f64, j as f64 / n as f64);
            let too_deep = match known_too_deep.take() {
                Some(depth) => depth,
                None => {
                    let pose = at(hi)?;
                    // Pressed to the allowed depth, no search would follow a pose too deep,
                    // so its depth is not needed: when the deepest point of the last pose is
                    // too deep at this one, so is the pose, and the query is saved (`too_deep_at`
                    // then holds that point's depth, a lower bound of the pose's).
                    if done.contact.max_penetration >= CLOSE_ENOUGH * limit {
                        if let Some(i) = done.contact.deepest_point {
                            let p = point_penetration(self.voxmap, self.shell, &pose, &self.params.contact, i)?;
                            if p > limit {
                                done.too_deep_at = Some(TooDeepPose {
                                    fraction: hi * scale,
                                    depth: p,
                                    queried: false,
                                });
                                return Ok(done);
                            }
                        }
                    }
                    done.queries += 1;
                    let Some(c) = self.checked(&pose, deadline)? else {
                        done.out_of_time = true;
                        return Ok(done);
                    };
                    if c.max_penetration <= limit {
                        (done.pose, done.contact, done.fraction) = (pose, c, hi * scale);
                        continue;
                    }
                    c.max_penetration
                }
            };
            done.too_deep_at = Some(TooDeepPose::queried(hi * scale, too_deep));
            // Too deep at `hi`, within the limit at `lo`: search between them for a pose just
            // within it, by false position (the depth is nearly linear along a sub-step), kept
            // off the bracket's ends so the bracket always shrinks; done once within the last
            // tenth of the allowed depth.
            let (mut ok, mut bad) = (lo, hi);
            let (mut depth_ok, mut depth_bad) = (done.contact.max_penetration, too_deep);
            for _ in 0..BISECTIONS {
                if depth_ok >= CLOSE_ENOUGH * limit {
                    break;
                }
                let t = ((CLOSE_ENOUGH * limit + limit) * 0.5 - depth_ok) / (depth_bad - depth_ok);
                let mid = ok + (bad - ok) * t.clamp(0.1, 0.9);
                let pose = at(mid)?;
                done.queries += 1;
                let Some(c) = self.checked(&pose, deadline)? else {
                    done.out_of_time = true;
                    break;
                };
                if c.max_penetration <= limit {
                    (ok, depth_ok) = (mid, c.max_penetration);
                    (done.pose, done.contact, done.fraction) = (pose, c, mid * scale);
                } else {
                    (bad, depth_bad) = (mid, c.max_penetration);
                }
            }
            return Ok(done);
        }
        Ok(done)
    }
}

/// Where an advancement got to.
pub(super) struct Advance {
    /// The pose reached and the contact there.
    pub(super) pose: Pose,
    pub(super) contact: Contact,
    /// The fraction of the motion made.
    pub(super) fraction: f64,
    /// Contact queries run.
    pub(super) queries: u32,
    /// Whether the time budget stopped it.
    pub(super) out_of_time: bool,
    /// The first pose found too deep.
    pub(super) too_deep_at: Option<TooDeepPose>,
}

/// A pose of an advancement found too deep.
#[derive(Clone, Copy, Debug)]
pub(super) struct TooDeepPose {
    /// Where, as a fraction of the motion.
    fraction: f64,
    /// How deep: the pose's depth when `queried`, else the depth of the point that proved it
    /// too deep (a lower bound of the pose's).
    depth: f64,
    queried: bool,
}

impl TooDeepPose {
    /// A pose's own depth, from a complete query (at a slide's end, perhaps within the limit).
    fn queried(fraction: f64, depth: f64) -> TooDeepPose {
        TooDeepPose {
            fraction,
            depth,
            queried: true,
        }
    }
}

/// `v` without its part against `n` (a contact's force or torque): what of a motion the contact
/// does not stop.
pub(super) fn not_into(v: DVec3, n: DVec3) -> DVec3 {
    let n = n.normalize_or_zero();
    v - n * v.dot(n).min(0.0)
}
