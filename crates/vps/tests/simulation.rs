//! The haptic loop (`vps::haptics::simulation`): no pop-through at speed, rest on a plane, a
//! smooth slide.

use glam::DVec3;

use vps::haptics::simulation::{BodyState, MassProperties, Simulation, SimulationParams, Step, TESTED_STIFFNESS_RATIO};
use vps::{shapes, CachedVoxmap, Pointshell, Pose};

mod common;
use common::contact::{moving_shell, static_voxmap};

/// Voxel size 0.1: the plane's top at z = 0, 6 × 6; a ball of radius 0.5 (pointshell voxels of
/// 0.05).
fn ball_over_plane() -> (f64, CachedVoxmap, Pointshell) {
    let s = 0.1;
    let plane = static_voxmap(
        shapes::cuboid(DVec3::new(-3.0, -3.0, -1.0), DVec3::new(3.0, 3.0, 0.0)),
        s,
    );
    (s, plane, moving_shell(shapes::sphere(DVec3::ZERO, 0.5, 24, 48), 0.05))
}

/// Voxel size 0.1: a wall 2 voxels thick, its faces at x = 0 and x = 0.2 on voxel faces; the
/// ball of [`ball_over_plane`].
fn ball_before_wall() -> (f64, CachedVoxmap, Pointshell) {
    let s = 0.1;
    let wall = static_voxmap(
        shapes::cuboid(DVec3::new(0.0, -3.0, -3.0), DVec3::new(2.0 * s, 3.0, 3.0)),
        s,
    );
    (s, wall, moving_shell(shapes::sphere(DVec3::ZERO, 0.5, 24, 48), 0.05))
}

fn at(x: f64, y: f64, z: f64) -> Pose {
    Pose::new([x, y, z], [1.0, 0.0, 0.0, 0.0]).unwrap()
}

/// The posed points of `shell` at `pose`.
fn posed<'a>(shell: &'a Pointshell, pose: &Pose) -> impl Iterator<Item = DVec3> + 'a {
    let pose = *pose;
    shell
        .points
        .iter()
        .map(move |p| pose.transform_point(shell.origin + p.as_dvec3()))
}

/// Issue 13's wall: 2 voxels thick, the device pushed straight through it at 10 voxels per
/// millisecond and held beyond. The object stays on the near side at every step (no point past
/// the wall's middle), and the device is pulled back.
#[test]
fn a_device_pushed_through_a_thin_wall_at_speed_leaves_the_object_on_the_near_side() {
    let (s, wall, ball) = ball_before_wall();
    let body = MassProperties::of_shell(&ball, 1.0);
    let params = SimulationParams::for_body(&body);
    let mut sim = Simulation::new(&wall, &ball, body, params, at(-1.0, 0.0, 0.0)).unwrap();
    let mut limited = 0;
    let mut last: Option<Step> = None;
    for i in 0..300 {
        // 10 voxels per step from x = −1 to x = 3, then held there.
        let device = at((-1.0 + (i + 1) as f64 * 10.0 * s).min(3.0), 0.0, 0.0);
        let step = sim.step(&device).unwrap();
        let deepest = posed(&ball, &step.pose).map(|p| p.x).fold(f64::NEG_INFINITY, f64::max);
        assert!(
            deepest < s,
            "step {i}: a point at x = {deepest}, past the wall's middle"
        );
        assert!(
            step.contact.max_penetration <= 0.25 * s + 1e-12,
            "step {i}: {:?}",
            step.contact
        );
        limited += step.limited as u32;
        last = Some(step);
    }
    let last = last.unwrap();
    assert!(limited > 0, "the advancement never had to stop the object");
    // At rest against the wall, the device 3.5 beyond the object's centre feels the spring.
    let pull = params.coupling.stiffness * (3.0 - sim.state().pose.translation.x);
    assert!(last.device_force.x < -0.9 * pull, "{:?}", last.device_force);
    // Straight on, nearly: the ball's pointshell is symmetric only up to its sampling (its
    // centre of mass lies 3.0·10⁻⁴ off its frame's origin, sideways), and the object comes to
    // rest about that far off the axis (3.7·10⁻⁴ when measured: 1.1·10⁻⁴ of the pull).
    let across = DVec3::new(0.0, last.device_force.y, last.device_force.z).length();
    assert!(across < 2e-4 * pull, "{:?}", last.device_force);
    assert!(
        last.contact.force.x < 0.0,
        "the wall pushes back: {:?}",
        last.contact.force
    );
}

/// Contact stiffnesses per point, as multiples of the default (the coupling's), that the
/// rest and passivity tests hold the loop to: the stated range of `docs/HAPTICS.md`.
const CONTACT_STIFFNESS_FACTORS: [f64; 6] = [1.0, 2.0, 4.0, 10.0, 100.0, TESTED_STIFFNESS_RATIO];

/// Issue 13's rest: the object let go above a plane with the device held 3 voxels below the
/// surface comes to rest (under 10⁻³ voxels per millisecond within 500 steps), in contact and
/// within the allowed depth, at every contact stiffness of [`CONTACT_STIFFNESS_FACTORS`].
#[test]
fn an_object_pulled_onto_a_plane_comes_to_rest() {
    for factor in CONTACT_STIFFNESS_FACTORS {
        comes_to_rest(factor);
    }
}

/// [`an_object_pulled_onto_a_plane_comes_to_rest`] at `factor` times the default contact
/// stiffness.
fn comes_to_rest(factor: f64) {
    let (s, plane, ball) = ball_over_plane();
    let body = MassProperties::of_shell(&ball, 1.0);
    let mut params = SimulationParams::for_body(&body);
    params.contact.stiffness *= factor;
    let mut sim = Simulation::new(&plane, &ball, body, params, at(0.1, 0.0, 0.5 + 3.0 * s)).unwrap();
    let device = at(0.1, 0.0, 0.5 - 3.0 * s);
    let (mut speeds, mut slowed) = (Vec::new(), 0);
    for i in 0..500 {
        let step = sim.step(&device).unwrap();
        slowed += (step.energy_removed > 0.0) as u32;
        assert!(step.contact.max_penetration <= 0.25 * s + 1e-12);
        // Settled, a step is one query that nothing stops.
        assert!(
            i < 400 || (step.queries == 1 && !step.limited),
            "contact stiffness ×{factor}, step {i}: {step:?}"
        );
        let st = sim.state();
        // Voxels per millisecond: the centre's, and the fastest point's from the spin.
        let speed = (st.velocity.length() + st.angular_velocity.length() * 0.5) * params.step / s;
        speeds.push(speed);
    }
    let last = *speeds.last().unwrap();
    eprintln!("rest, contact stiffness ×{factor}: {slowed} steps of 500 slowed to stay passive, {last:.1e} voxels/ms");
    assert!(
        last < 1e-3,
        "contact stiffness ×{factor}: still moving at {last} voxels/ms; speeds {:?}",
        &speeds[480..]
    );
    let st = sim.state();
    let c = vps::contact(&plane, &ball, &st.pose, &params.contact).unwrap();
    assert!(c.points_in_contact > 0 && c.force.z > 0.0, "{c:?}");
    // At rest the contact holds the coupling's pull.
    let pull = params.coupling.stiffness * (st.pose.translation.z - device.translation.z);
    assert!(
        (c.force.z - pull).abs() < 0.01 * pull,
        "contact stiffness ×{factor}: contact {} against pull {pull}",
        c.force.z
    );
}

/// Issue 13's slide: a box turned 17° about the vertical, pushed along a plane whose top lies
/// off the lattice, the device 3 voxels below the surface and moving at 0.1 voxel per
/// millisecond at 30° to the axes: once it is under way, the device force is smooth (std/mean
/// under 2 %) and the object follows the device.
#[test]
fn a_box_pushed_along_a_plane_slides_with_a_smooth_force() {
    let s = 0.1;
    let top = 0.037;
    let plane = static_voxmap(
        shapes::cuboid(DVec3::new(-5.0, -5.0, -1.0), DVec3::new(5.0, 5.0, top)),
        s,
    );
    let cube = moving_shell(shapes::cuboid(DVec3::splat(-0.4), DVec3::splat(0.4)), 0.05);
    let body = MassProperties::of_shell(&cube, 1.0);
    let params = SimulationParams::for_body(&body);
    let turn = glam::DQuat::from_rotation_z(17f64.to_radians());
    let q = [turn.w, turn.x, turn.y, turn.z];
    let pose = |p: DVec3| Pose::new(p.to_array(), q).unwrap();
    let heading = DVec3::new(30f64.to_radians().cos(), 30f64.to_radians().sin(), 0.0);
    let start = DVec3::new(-2.5, -1.5, top + 0.4 + 0.01);
    let mut sim = Simulation::new(&plane, &cube, body, params, pose(start)).unwrap();
    let mut forces = Vec::new();
    for i in 0..700 {
        let device = start + heading * (i as f64 * 0.1 * s) - DVec3::Z * (0.01 + 3.0 * s);
        let step = sim.step(&pose(device)).unwrap();
        assert!(step.contact.max_penetration <= 0.25 * s + 1e-12);
        if i >= 200 {
            forces.push(step.device_force.length());
            let lag = (sim.state().pose.translation - device).truncate().length();
            assert!(lag < 0.1 * s, "step {i}: {lag} behind the device");
        }
    }
    let mean = forces.iter().sum::<f64>() / forces.len() as f64;
    let std = (forces.iter().map(|f| (f - mean).powi(2)).sum::<f64>() / forces.len() as f64).sqrt();
    assert!(mean > 0.0);
    assert!(std / mean < 0.02, "std/mean {} over the slide; mean {mean}", std / mean);
    eprintln!(
        "slide: device force mean {mean:.1}, std/mean {:.4} %",
        100.0 * std / mean
    );
}

/// Issue 13's passivity: under random device motions in and out of contact, the object's
/// energy (kinetic, the coupling's springs, the contact's springs `Σ ½·K·w·d²`) never rises
/// by more than the work the device did on it through the coupling in that step, at every
/// contact stiffness of [`CONTACT_STIFFNESS_FACTORS`].
#[test]
fn random_device_motions_in_contact_never_add_energy() {
    for factor in CONTACT_STIFFNESS_FACTORS {
        random_motions_stay_passive(factor);
    }
}

/// [`random_device_motions_in_contact_never_add_energy`] at `factor` times the default contact
/// stiffness.
fn random_motions_stay_passive(factor: f64) {
    let (s, plane, ball) = ball_over_plane();
    let body = MassProperties::of_shell(&ball, 1.0);
    let mut params = SimulationParams::for_body(&body);
    params.contact.stiffness *= factor;
    let mut rng = shapes::SplitMix(5);
    let mut sim = Simulation::new(&plane, &ball, body, params, at(0.0, 0.0, 0.5 + s)).unwrap();
    let mut balance = EnergyBalance::new(&plane, &ball, &body, params, &sim.state().pose);
    let mut device = DVec3::new(0.0, 0.0, 0.5 + s);
    let (mut in_contact, mut slowed, mut worst) = (0, 0, f64::NEG_INFINITY);
    for i in 0..600 {
        // A random walk of the hand, up to ±3 voxels about the resting height, ±1 voxel/ms.
        let before = device;
        device += DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)) * s;
        device.z = device.z.clamp(0.5 - 3.0 * s, 0.5 + 3.0 * s);
        let state = *sim.state();
        let step = sim.step(&at(device.x, device.y, device.z)).unwrap();
        let (before, device) = (at(before.x, before.y, before.z), at(device.x, device.y, device.z));
        worst = worst.max(balance.check(i, &state, &before, &device, &step, sim.state()));
        in_contact += (step.contact.points_in_contact > 0) as u32;
        slowed += (step.energy_removed > 0.0) as u32;
    }
    assert!(in_contact > 100, "only {in_contact} steps in contact");
    eprintln!(
        "passivity, contact stiffness ×{factor}: largest gain over the device's work {worst:.3e}, \
         {in_contact} steps in contact, {slowed} slowed to stay passive"
    );
}

/// Issue 13's passivity for a device that turns as well: a brick of 0.8 × 0.6 × 0.4
/// (its three moments of inertia unequal) on the plane of [`ball_over_plane`], its device on a random walk in position (±1 voxel a millisecond, up to
/// 3 voxels into the plane) and in orientation (±0.05 radian about each axis a millisecond,
/// within 0.6 radian of upright), so that its edges and corners dig in and the contact pushes
/// with a torque: the angular coupling and the angular bound of the contact's stiffness are
/// held to the same inequality, at every contact stiffness of [`CONTACT_STIFFNESS_FACTORS`].
#[test]
fn random_device_turns_in_contact_never_add_energy() {
    for factor in CONTACT_STIFFNESS_FACTORS {
        random_turns_stay_passive(factor);
    }
}

/// [`random_device_turns_in_contact_never_add_energy`] at `factor` times the default contact
/// stiffness.
fn random_turns_stay_passive(factor: f64) {
    let (s, plane, _) = ball_over_plane();
    let half = DVec3::new(0.4, 0.3, 0.2);
    let brick = moving_shell(shapes::cuboid(-half, half), 0.05);
    let body = MassProperties::of_shell(&brick, 1.0);
    let moments = DVec3::new(body.inertia.x_axis.x, body.inertia.y_axis.y, body.inertia.z_axis.z);
    assert!(moments.x < 0.9 * moments.y && moments.y < 0.9 * moments.z, "{moments}");
    let mut params = SimulationParams::for_body(&body);
    params.contact.stiffness *= factor;
    let rest = half.z + s;
    let mut rng = shapes::SplitMix(11);
    let mut device = at(0.0, 0.0, rest);
    let mut sim = Simulation::new(&plane, &brick, body, params, device).unwrap();
    let mut balance = EnergyBalance::new(&plane, &brick, &body, params, &sim.state().pose);
    let (mut in_contact, mut torqued, mut slowed, mut backed_off, mut worst) = (0, 0, 0, 0, f64::NEG_INFINITY);
    for i in 0..600 {
        let before = device;
        let mut p =
            before.translation + DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)) * s;
        p.z = p.z.clamp(rest - 3.0 * s, rest + 3.0 * s);
        let spin = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)) * 0.05;
        let mut q = glam::DQuat::from_scaled_axis(spin) * before.rotation;
        if q.angle_between(glam::DQuat::IDENTITY) > 0.6 {
            q = glam::DQuat::from_scaled_axis(-spin) * before.rotation;
        }
        device = Pose::new(p.to_array(), [q.w, q.x, q.y, q.z]).unwrap();
        let state = *sim.state();
        let step = sim.step(&device).unwrap();
        assert!(step.contact.max_penetration <= 0.25 * s + 1e-12, "step {i}");
        worst = worst.max(balance.check(i, &state, &before, &device, &step, sim.state()));
        in_contact += (step.contact.points_in_contact > 0) as u32;
        // A contact torque about the centre (the frame's origin) with an arm of at least 0.1, a
        // half of the brick's least half side: an edge or a corner, not a face, bears.
        let arm = step.contact.torque.length() / step.contact.force.length().max(f64::MIN_POSITIVE);
        torqued += (step.contact.points_in_contact > 0 && arm > 0.1) as u32;
        slowed += (step.energy_removed > 0.0) as u32;
        backed_off += step.backed_off as u32;
    }
    assert!(in_contact > 100, "only {in_contact} steps in contact");
    assert!(torqued > 100, "only {torqued} steps with a contact torque");
    eprintln!(
        "passivity with turns, contact stiffness ×{factor}: largest gain over the device's work {worst:.3e}, \
         {in_contact} steps in contact, {torqued} with a torque, {slowed} slowed to stay passive, {backed_off} backed off"
    );
}

/// Issue 13's passivity, step by step: the object's energy (kinetic, the coupling's springs,
/// the contact's springs `Σ ½·K·w·d²`, measured point by point) may rise in a step by at most
/// the work the device did on it through the coupling: the coupling's force and torque on the
/// object at the start and end of the step, averaged (trapezoid rule), times the device's
/// displacement (of the object's centre of mass carried by the device's pose) and rotation
/// vector, the springs' ends moving with the hand.
struct EnergyBalance<'a> {
    voxmap: &'a CachedVoxmap,
    shell: &'a Pointshell,
    params: SimulationParams,
    /// The object's mass properties (the centre, where the linear spring pulls, in the
    /// pointshell's frame).
    body: MassProperties,
    /// The object's energy after the last step checked.
    energy: f64,
}

impl<'a> EnergyBalance<'a> {
    /// The balance of `body`, at rest at `start`.
    fn new(
        voxmap: &'a CachedVoxmap,
        shell: &'a Pointshell,
        body: &MassProperties,
        params: SimulationParams,
        start: &Pose,
    ) -> Self {
        let mut balance = EnergyBalance {
            voxmap,
            shell,
            params,
            body: *body,
            energy: 0.0,
        };
        balance.energy = balance.contact_energy(start);
        balance
    }

    /// The energy in the contact's springs at `pose`.
    fn contact_energy(&self, pose: &Pose) -> f64 {
        let grid = *self.voxmap.grid();
        let s = grid.voxel_size;
        let mut cur = self.voxmap.cursor();
        let mut u_c = 0.0;
        for (p, &w) in posed(self.shell, pose).zip(&self.shell.weights) {
            let d = s * cur.distance_at((p - grid.origin) / s);
            if d > 0.0 {
                u_c += 0.5 * self.params.contact.stiffness * d * d * w as f64;
            }
        }
        u_c
    }

    /// Step `i`, from the object in `state` to `after` with the device moving from `before`
    /// to `device`: asserts it made no energy from nothing (beyond 10⁻⁹ of the energy,
    /// rounding), and, after the first step (whose device velocity the loop takes as zero),
    /// that the step reports the same balance; returns what it made (negative when it lost
    /// some). Every energy is computed here, from the states and poses.
    fn check(
        &mut self,
        i: usize,
        state: &BodyState,
        before: &Pose,
        device: &Pose,
        step: &Step,
        after: &BodyState,
    ) -> f64 {
        let (c, h, m) = (self.params.coupling, self.params.step, self.body.mass);
        let centre = |p: &Pose| p.transform_point(self.body.centre);
        let (moved, turned) = (centre(device) - centre(before), turn_between(before, device));
        let pull_before =
            (centre(before) - centre(&state.pose)) * c.stiffness + (moved / h - state.velocity) * c.damping;
        let twist_before = turn_between(&state.pose, before) * c.angular_stiffness
            + (turned / h - state.angular_velocity) * c.angular_damping;
        let work =
            0.5 * (pull_before - step.device_force).dot(moved) + 0.5 * (twist_before - step.device_torque).dot(turned);
        let r = after.pose.matrix();
        let inertia = r * self.body.inertia * r.transpose();
        let kinetic = 0.5 * m * after.velocity.length_squared()
            + 0.5 * after.angular_velocity.dot(inertia * after.angular_velocity);
        let offset = centre(device) - centre(&after.pose);
        let twist = turn_between(&after.pose, device);
        let springs = 0.5 * c.stiffness * offset.length_squared() + 0.5 * c.angular_stiffness * twist.length_squared();
        let now = kinetic + springs + self.contact_energy(&after.pose);
        let gain = now - self.energy - work;
        assert!(
            gain <= 1e-9 * now.max(1.0),
            "step {i}: energy {} -> {now}, device work {work}: {gain} made from nothing",
            self.energy
        );
        assert!(
            i == 0 || (gain - step.energy_gain).abs() <= 1e-9 * now.max(1.0),
            "step {i}: the step reports a gain of {}, the test finds {gain}",
            step.energy_gain
        );
        self.energy = now;
        gain
    }
}

/// The rotation vector (axis times angle, the shorter way round) that turns `from` into `to`.
fn turn_between(from: &Pose, to: &Pose) -> DVec3 {
    vps::geometry::rotation_vector(to.rotation * from.rotation.inverse())
}

/// Pressed to the allowed depth and pulled sideways, the object slides, and passively. The
/// device goes 17 voxels into a ball of radius 3 (voxel 0.1) under the ball of
/// [`ball_over_plane`], then round it at 0.2 voxel per millisecond: the coupling presses the
/// object to the depth limit, where the interpolated field (distances rounded to 1/32 voxel)
/// leans by a few hundredths from the contact force's plane, so a slide across that force
/// alone goes deeper than allowed; the object must still follow the device round the ball,
/// its energy never rising by more than the device's work.
#[test]
fn an_object_pressed_to_the_depth_limit_still_slides() {
    let (s, big, ball) = ball_on_big_sphere();
    let body = MassProperties::of_shell(&ball, 1.0);
    let params = SimulationParams::for_body(&body);
    let mut sim = Simulation::new(&big, &ball, body, params, at(0.0, 0.0, PRESSED_SLIDE_TOP)).unwrap();
    let mut balance = EnergyBalance::new(&big, &ball, &body, params, &sim.state().pose);
    let mut device = DVec3::new(0.0, 0.0, PRESSED_SLIDE_TOP);
    let (mut limited, mut stalled, mut one_query) = (0, 0, 0);
    for i in 0..500 {
        let before = device;
        device = pressed_slide_device(i);
        let state = *sim.state();
        let step = sim.step(&at(device.x, device.y, device.z)).unwrap();
        assert!(step.contact.max_penetration <= 0.25 * s + 1e-12, "step {i}");
        balance.check(
            i,
            &state,
            &at(before.x, before.y, before.z),
            &at(device.x, device.y, device.z),
            &step,
            sim.state(),
        );
        if i > 150 {
            limited += step.limited as u32;
            one_query += (step.limited && step.queries == 1) as u32;
            stalled += ((step.pose.translation - state.pose.translation).length() < 1e-3 * s) as u32;
        }
    }
    // The object, held on the ball's surface, is pulled to where the line from the ball's
    // centre to the device meets it.
    let (object, device) = (sim.state().pose.translation, device);
    let angle = object.angle_between(device).to_degrees();
    eprintln!(
        "pressed slide: {limited} of 349 steps at the limit ({one_query} of one query), {stalled} stalled, \
         {angle:.2}° from the device"
    );
    assert!(limited > 100, "only {limited} steps at the limit: not pressed");
    assert!(stalled < 5, "{stalled} of 349 steps stalled");
    // A push on into the wall is proved too deep by the last deepest point, without a query,
    // so most pressed steps run only their slide's; and a slide so proved blocked is lifted by
    // that point's gain, unqueried (321 of 349 steps of one query; 275 when the lifted slide
    // queried the blocked slide's end, two queries at least before either).
    assert!(
        one_query * 100 > limited * 85,
        "{one_query} of {limited} pressed steps took one query"
    );
    assert!(angle < 5.0, "the object is {angle}° round the ball from the device");
}

/// Where the shell's frame has its origin is the user's choice (a CAD part's is often far from
/// the part), and must not change the motion: the pressed slide round the ball, with the
/// ball's frame origin at its centre and 20 units away (its points and the device's poses moved
/// to match), keeps the centre of mass on the same path, up to rounding (1.2·10⁻¹³ when
/// measured). A stop and a slide that cut the spin about the contact torque at the frame's
/// origin, instead of about the centre of mass, made the paths part by 2.7·10⁻⁴.
#[test]
fn the_motion_does_not_depend_on_where_the_frame_origin_is() {
    let (s, big, ball) = ball_on_big_sphere();
    let path = |offset: DVec3| -> Vec<DVec3> {
        let mut shell = ball.clone();
        shell.origin += offset;
        let body = MassProperties::of_shell(&shell, 1.0);
        let params = SimulationParams::for_body(&body);
        let start = DVec3::new(0.0, 0.0, PRESSED_SLIDE_TOP) - offset;
        let mut sim = Simulation::new(&big, &shell, body, params, at(start.x, start.y, start.z)).unwrap();
        (0..300)
            .map(|i| {
                let device = pressed_slide_device(i) - offset;
                let step = sim.step(&at(device.x, device.y, device.z)).unwrap();
                step.pose.transform_point(body.centre)
            })
            .collect()
    };
    let (near, far) = (path(DVec3::ZERO), path(DVec3::new(0.0, 20.0, 0.0)));
    let apart = near.iter().zip(&far).map(|(a, b)| a.distance(*b)).fold(0.0, f64::max);
    eprintln!("frame origin 20 away: the centre of mass at most {apart:.2e} off its path");
    assert!(apart < 1e-7 * s, "the centre of mass left its path by {apart}");
}

/// Voxel size 0.1: a sphere of radius 3 at the origin, and the ball of [`ball_over_plane`].
fn ball_on_big_sphere() -> (f64, CachedVoxmap, Pointshell) {
    let s = 0.1;
    let big = static_voxmap(shapes::sphere(DVec3::ZERO, 3.0, 96, 192), s);
    (s, big, moving_shell(shapes::sphere(DVec3::ZERO, 0.5, 24, 48), 0.05))
}

/// Where the ball of [`ball_on_big_sphere`] starts the pressed slide: resting on the top.
const PRESSED_SLIDE_TOP: f64 = 3.5 + 0.01;

/// The device of the pressed slide at step `i`: 100 steps down from the top, 17 voxels in, then
/// round the big sphere at 0.2 voxel per millisecond at the object's radius.
fn pressed_slide_device(i: usize) -> DVec3 {
    let top = PRESSED_SLIDE_TOP;
    if i < 100 {
        DVec3::new(0.0, 0.0, top - 0.017 * i as f64)
    } else {
        let turn = 0.02 * (i - 100) as f64 / top;
        DVec3::new(turn.sin(), 0.0, turn.cos()) * (top - 1.7)
    }
}

/// The lowest z of `shell`'s points at `pose`.
fn lowest(shell: &Pointshell, pose: &Pose) -> f64 {
    posed(shell, pose).map(|p| p.z).fold(f64::INFINITY, f64::min)
}

/// What a peg did on its way down a hole: the lowest its tip went, the largest device force,
/// the largest depth of contact.
struct Insertion {
    tip: f64,
    largest_force: f64,
    deepest: f64,
}

/// A peg of radius 0.4 and length 2 with its bottom at its frame's origin.
fn peg_shell() -> Pointshell {
    moving_shell(shapes::cylinder(DVec3::ZERO, 0.4, 2.0, 48), 0.05)
}

/// The peg of [`peg_shell`] (pointshell voxels of 0.05), tilted 2° about x, lowered
/// along the axis of a hole of `hole_radius` in a plate 1 thick (top z = 1, far side z = 0,
/// voxels of 0.1) at 0.5 voxel per millisecond from 0.3 above it to 1 below the far side, then
/// held there.
fn insert_peg(hole_radius: f64) -> Insertion {
    let s = 0.1;
    let plate = static_voxmap(shapes::plate_with_hole(DVec3::ZERO, 2.0, 0.0, 1.0, hole_radius, 64), s);
    let peg = peg_shell();
    let body = MassProperties::of_shell(&peg, 1.0);
    let params = SimulationParams::for_body(&body);
    let tilt = glam::DQuat::from_rotation_x(2f64.to_radians());
    let q = [tilt.w, tilt.x, tilt.y, tilt.z];
    let pose = |z: f64| Pose::new([0.0, 0.0, z], q).unwrap();
    let mut sim = Simulation::new(&plate, &peg, body, params, pose(1.3)).unwrap();
    let mut out = Insertion {
        tip: f64::INFINITY,
        largest_force: 0.0,
        deepest: 0.0,
    };
    for i in 0..600 {
        let step = sim.step(&pose((1.3 - i as f64 * 0.5 * s).max(-1.0))).unwrap();
        out.tip = out.tip.min(lowest(&peg, &step.pose));
        out.largest_force = out.largest_force.max(step.device_force.length());
        out.deepest = out.deepest.max(step.contact.max_penetration);
    }
    out
}

/// Issue 13's peg in hole: with a hole 1.5 voxels wider than the peg, the slightly tilted peg
/// goes through (its tip passes the plate's far side) with a bounded device force; a hole
/// narrower than the peg stops it on the plate, the device pulled back.
#[test]
fn a_peg_goes_into_a_wider_hole_and_not_into_a_narrower_one() {
    let s = 0.1;
    let wide = insert_peg(0.4 + 1.5 * s);
    assert!(wide.tip < -0.5, "the peg's tip stopped at z = {}", wide.tip);
    let narrow = insert_peg(0.35);
    // The peg's rim rests on the hole's edge; the middle of its bottom face dips into the hole
    // by the tilt, the allowed depth and the rounding of the edge by the interpolated field
    // (measured 0.05, half a voxel), far from the 2 it would go through.
    assert!(narrow.tip > 1.0 - s, "the peg went {} into the narrow hole", narrow.tip);
    assert!(narrow.deepest <= 0.25 * s + 1e-12);
    // Going through, the device force stays below the coupling's pull over 5 voxels (it is
    // mostly the damper's as the device starts moving, measured 15,300 against 20,000);
    // blocked, the device (2.2 below where the peg rests) feels the coupling's full pull.
    let k = SimulationParams::for_body(&MassProperties::of_shell(&peg_shell(), 1.0))
        .coupling
        .stiffness;
    assert!(
        wide.largest_force < k * 5.0 * s,
        "{} against {}",
        wide.largest_force,
        k * 5.0 * s
    );
    assert!(
        narrow.largest_force > k * 2.0,
        "{} against {}",
        narrow.largest_force,
        k * 2.0
    );
    eprintln!(
        "peg: wide hole tip {:.3}, largest device force {:.1}, deepest {:.4}; narrow hole tip {:.3}, force {:.1}",
        wide.tip, wide.largest_force, wide.deepest, narrow.tip, narrow.largest_force
    );
}

/// With a step budget too short for any query, the object moves only to poses a complete
/// query checked: it stays put and says so, and never goes past the wall; with a budget that
/// is never spent, the run is the exact one (to rounding: the time-critical walk sums the
/// points in another order).
#[test]
fn a_step_budget_stops_the_object_short_never_deeper() {
    let (s, wall, ball) = ball_before_wall();
    let body = MassProperties::of_shell(&ball, 1.0);
    let exact = SimulationParams::for_body(&body);
    let run = |params: SimulationParams| {
        let mut sim = Simulation::new(&wall, &ball, body, params, at(-1.0, 0.0, 0.0)).unwrap();
        (0..60)
            .map(|i| {
                sim.step(&at((-1.0 + (i + 1) as f64 * 10.0 * s).min(3.0), 0.0, 0.0))
                    .unwrap()
            })
            .collect::<Vec<Step>>()
    };
    let starved = run(SimulationParams {
        step_budget: Some(std::time::Duration::from_nanos(1)),
        ..exact
    });
    assert!(starved.iter().all(|st| st.out_of_time && !st.limited));
    assert!(starved
        .iter()
        .all(|st| st.pose.translation == DVec3::new(-1.0, 0.0, 0.0)));
    let generous = run(SimulationParams {
        step_budget: Some(std::time::Duration::from_secs(60)),
        ..exact
    });
    let reference = run(exact);
    assert!(generous.iter().all(|st| !st.out_of_time));
    for (i, (g, r)) in generous.iter().zip(&reference).enumerate() {
        assert!(
            (g.pose.translation - r.pose.translation).length() < 1e-9,
            "step {i}: {g:?} vs {r:?}"
        );
        assert_eq!(g.limited, r.limited, "step {i}");
    }
}
