//! The walks of the sphere tree: the exact one, on the calling thread and the pool, and the
//! time-critical one, breadth-first until its deadline.

use std::time::Instant;

use super::share::{helpers, share};
use super::{Class, Contact, Frame, BLOCK_POINTS};
use crate::haptics::cache::Cursor;
use crate::pointshell::{NodeLoad, SphereNode};
use crate::storage::StorageError;

/// The exact walk tests the nodes down to the first of at most this many points (the tasks) on
/// the calling thread, which decides from the points left in the tasks whether to share them
/// with the pool; the nodes below a task are tested by the thread that walks it. Testing every
/// node above the blocks on one thread kept the other idle for a quarter of the first query
/// after opening (its node tests decode bricks).
pub(super) const TASK_POINTS: u32 = 4 * BLOCK_POINTS;

/// The time-critical walk checks the clock every this many nodes, and also before every
/// leaf's points and every node whose brick is not in the cursor's table.
const CLOCK_EVERY: usize = 16;

/// How often the time-critical walk plans one level at most: once before it starts, and again
/// after each stretch it planned, with the pace measured meanwhile.
const PLANS_PER_LEVEL: usize = 4;

/// Planning the time-critical walk: the time per node test and per point tested assumed before
/// any is measured, and the least assumed after (a level of a few nodes measures mostly the
/// clock).
const INITIAL_NODE_SECONDS: f64 = 100e-9;
const MIN_NODE_SECONDS: f64 = 10e-9;
const INITIAL_POINT_SECONDS: f64 = 50e-9;
const MIN_POINT_SECONDS: f64 = 2e-9;

/// What the time-critical walk has measured of its own speed over the levels refined so far:
/// node tests and leaves' points apart, since a leaf costs its points (about 1 µs against
/// 0.1–0.3 µs a node test in the built-in plunge), and one mean over both misjudged the level
/// where the leaves begin.
#[derive(Default)]
struct Pace {
    node_seconds: f64,
    nodes: usize,
    point_seconds: f64,
    points: u64,
}

impl Pace {
    /// Seconds a node test takes, and so a stand-in, which reads about as much.
    fn node(&self) -> f64 {
        match self.nodes {
            0 => INITIAL_NODE_SECONDS,
            n => (self.node_seconds / n as f64).max(MIN_NODE_SECONDS),
        }
    }

    /// Seconds a leaf's point takes.
    fn point(&self) -> f64 {
        match self.points {
            0 => INITIAL_POINT_SECONDS,
            n => (self.point_seconds / n as f64).max(MIN_POINT_SECONDS),
        }
    }
}

/// What the exact walk below a node adds: the sums of its blocks, in block order, and the
/// nodes it tested and culled above them.
#[derive(Default)]
struct BlockSums {
    parts: Vec<Contact>,
    nodes_tested: u64,
    nodes_culled: u64,
}

impl BlockSums {
    /// These sums followed by `o`'s.
    fn append(&mut self, mut o: BlockSums) {
        self.parts.append(&mut o.parts);
        self.nodes_tested += o.nodes_tested;
        self.nodes_culled += o.nodes_culled;
    }
}

impl Frame<'_> {
    /// Depth-first walk below `root` (already found not outside when `root_tested`), left
    /// child first, so points are summed in index order. Below a node proved inside, every
    /// point is tested without testing more nodes.
    ///
    /// Nodes whose points follow one another are tested as one range, so the batches of
    /// `test_points` stay full (a leaf holds 8 to 16 points): the same points in the same
    /// order, so the same sums. Errors met by `cur` on the way are returned here.
    pub(super) fn walk(
        &self,
        cur: &mut Cursor<'_>,
        root: usize,
        root_tested: bool,
        acc: &mut Contact,
    ) -> Result<(), StorageError> {
        let mut stack: Vec<(usize, bool)> = Vec::with_capacity(64);
        stack.push((root, root_tested));
        let mut pending = 0..0;
        while let Some((i, tested)) = stack.pop() {
            let node = &self.nodes[i];
            let mut inside = false;
            if !tested {
                acc.nodes_tested += 1;
                match self.classify(cur, node)? {
                    Class::Outside => {
                        acc.nodes_culled += 1;
                        continue;
                    }
                    Class::Inside => inside = true,
                    Class::Deep => {
                        self.test_points(cur, std::mem::replace(&mut pending, 0..0), acc);
                        self.test_points_deep(node.points(), acc);
                        continue;
                    }
                    Class::Straddles => {}
                }
            }
            match node.children() {
                Some([a, b]) if !inside => {
                    stack.push((b, false));
                    stack.push((a, false));
                }
                _ => {
                    let points = node.points();
                    if points.start == pending.end {
                        pending.end = points.end;
                    } else {
                        self.test_points(cur, std::mem::replace(&mut pending, points), acc);
                    }
                }
            }
        }
        self.test_points(cur, pending, acc);
        cur.check()
    }

    /// The cut of the tree at `max_points`: its highest nodes of at most `max_points` points, in
    /// point order (the blocks, with [`BLOCK_POINTS`]; the tasks, with [`TASK_POINTS`]). With
    /// `cull`, every node down to them is tested, those under a culled node are dropped, and
    /// those returned have been tested.
    pub(super) fn cut_at(&self, max_points: u32, cull: bool, acc: &mut Contact) -> Result<Vec<usize>, StorageError> {
        self.cut_waking(max_points, cull, false, acc)
    }

    /// [`Frame::cut_at`], and with `wake`, once the root is not culled, [`wake_pool`].
    fn cut_waking(
        &self,
        max_points: u32,
        cull: bool,
        wake: bool,
        acc: &mut Contact,
    ) -> Result<Vec<usize>, StorageError> {
        let mut out = Vec::new();
        if self.nodes.is_empty() {
            return Ok(out);
        }
        let mut cur = cull.then(|| self.voxmap.cursor());
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i];
            if let Some(cur) = cur.as_mut() {
                acc.nodes_tested += 1;
                if self.is_outside(cur, node)? {
                    acc.nodes_culled += 1;
                    continue;
                }
            }
            if wake && i == 0 {
                wake_pool();
            }
            match node.children() {
                Some([a, b]) if node.point_count > max_points => {
                    stack.push(b);
                    stack.push(a);
                }
                _ => out.push(i),
            }
        }
        cur.map_or(Ok(()), |cur| cur.finish())?;
        Ok(out)
    }

    /// The exact walk: the nodes down to the tasks (the first of at most [`TASK_POINTS`]
    /// points) tested here; when more than one task is left and they hold
    /// `parallel_min_points` or more, the tasks shared between this thread and the pool
    /// ([`share`]), else all walked here. Each thread walks its tasks through one cursor, and
    /// the block sums are added in block order, whoever made them.
    pub(super) fn walk_exact(&self, parallel_min_points: u64, acc: &mut Contact) -> Result<(), StorageError> {
        // A query that may go parallel wakes as many pool threads as it would share with as
        // soon as the root is not culled (see `wake_pool`); it may yet walk all here.
        let wake = self.points.len() as u64 >= parallel_min_points;
        let tasks = self.cut_waking(TASK_POINTS, true, wake, acc)?;
        let points: u64 = tasks.iter().map(|&t| self.nodes[t].point_count as u64).sum();
        let mut sums = BlockSums::default();
        let task = |cur: &mut Cursor<'_>, t: usize| {
            let mut task_sums = BlockSums::default();
            self.sums_below(cur, t, &mut task_sums).map(|()| task_sums)
        };
        if points >= parallel_min_points && tasks.len() > 1 {
            let done = share(tasks.len(), || self.voxmap.cursor(), |cur, k| task(cur, tasks[k]))?;
            for t in done {
                sums.append(t);
            }
        } else {
            // One list of sums for all the tasks: no list of its own to append for each.
            let mut cur = self.voxmap.cursor();
            for &t in &tasks {
                self.sums_below(&mut cur, t, &mut sums)?;
            }
        }
        acc.nodes_tested += sums.nodes_tested;
        acc.nodes_culled += sums.nodes_culled;
        for part in &sums.parts {
            acc.merge(part);
        }
        Ok(())
    }

    /// Add to `sums` those of the blocks below node `root` (tested, not culled), in block
    /// order, through `cur`: its descendants of more than [`BLOCK_POINTS`] points tested on
    /// the way. Each block is summed apart, as the brute force sums it.
    fn sums_below(&self, cur: &mut Cursor<'_>, root: usize, sums: &mut BlockSums) -> Result<(), StorageError> {
        let node = &self.nodes[root];
        let Some(halves) = node.children().filter(|_| node.point_count > BLOCK_POINTS) else {
            let mut part = Contact::default();
            self.walk(cur, root, true, &mut part)?;
            sums.parts.push(part);
            return Ok(());
        };
        for i in halves {
            sums.nodes_tested += 1;
            if self.is_outside(cur, &self.nodes[i])? {
                sums.nodes_culled += 1;
            } else {
                self.sums_below(cur, i, sums)?;
            }
        }
        Ok(())
    }

    /// Whether testing `node` reads a brick already in `cur`'s table (or none): one not at hand
    /// may have to be decoded, about 4 µs, so the clock is read first.
    fn at_hand(&self, cur: &Cursor<'_>, node: &SphereNode) -> bool {
        let (_, u) = self.place(node.center());
        !cur.contains(u) || cur.in_table([u.x as u32, u.y as u32, u.z as u32])
    }

    /// How many of `level`'s first nodes to refine with `left` seconds left and the stand-ins
    /// of `owed` nodes already due (children of nodes refined). Refining a node costs a node
    /// test, and then its points if it is a leaf, or the stand-ins of its two children if the
    /// budget runs out below; leaving it costs its own stand-in (about a node test). The most
    /// nodes whose refinement and the others' stand-ins fit in `left`.
    fn refinable(&self, level: &[(usize, Option<usize>)], owed: usize, left: f64, pace: &Pace) -> usize {
        let (node, point) = (pace.node(), pace.point());
        let mut total = (level.len() + owed) as f64 * node;
        for (at, &(i, _)) in level.iter().enumerate() {
            let n = &self.nodes[i];
            total += match n.children() {
                Some(_) => 2.0 * node,
                None => n.point_count as f64 * point,
            };
            if total > left {
                return at;
            }
        }
        level.len()
    }

    /// Stand-in for the untested points of node `j` when the budget has run out: its points,
    /// as if all were as deep as its centre, pushing with the node's summed load
    /// ([`NodeLoad`]), plus a bound on the error (see `docs/HAPTICS.md`).
    ///
    /// With distances, a node whose centre's brick is cold ([`Cursor::is_cold`]: a stored
    /// brick to decode) reads no brick when its `parent` is given and the parent's centre lies
    /// in the grid in a brick at hand (the parent's test read it): the depth at the parent's
    /// centre is carried to the node's along the slope there, and `v_max` of the bound is
    /// taken from the parent's centre and radius, which hold the node's points too (the
    /// torque's lever stays the node's own). Reading bricks after the deadline made the
    /// budgeted queries overrun (`docs/PERFORMANCE.md`).
    pub(super) fn approximate(
        &self,
        cur: &mut Cursor<'_>,
        j: usize,
        parent: Option<usize>,
        acc: &mut Contact,
    ) -> Result<(), StorageError> {
        let node = &self.nodes[j];
        acc.nodes_approximated += 1;
        acc.points_approximated += node.point_count as u64;
        let (r, u) = self.place(node.center());
        let from_parent = parent
            .filter(|_| self.reads_distances() && cur.contains(u))
            .filter(|_| cur.is_cold([u.x as u32, u.y as u32, u.z as u32]))
            .map(|p| (&self.nodes[p], self.place(self.nodes[p].center()).1))
            .filter(|&(_, up)| cur.contains(up) && !cur.is_cold([up.x as u32, up.y as u32, up.z as u32]));
        // The sphere the bound is taken over: the node's, or its parent's.
        let (radius, at) = from_parent.map_or((node.radius, u), |(p, up)| (p.radius, up));
        let looked_up = cur.in_grid(at);
        cur.check()?;
        let inside_grid = looked_up.is_some();
        let (value, v) = looked_up.unwrap_or((self.outside, [0; 3]));
        // Values change by at most 1 per voxel step, except one step of 2 from −1 to +1
        // across a diagonal, and a point within r is at most floor(r/s) + 1 steps away.
        // An interpolated distance reads one voxel further, a sharp one two.
        let steps = (radius as f64 * self.inv_s).floor() as i32 + self.reach_voxels();
        let v_max = if inside_grid {
            (value as i32 + steps + 1).min(self.layers + 1)
        } else {
            self.layers + 1
        };
        if v_max < 0 {
            return Ok(());
        }
        let count = node.point_count as f64;
        // Each point's penetration is at most s·v_max plus its distance to its voxel centre;
        // an interpolated distance, at most the reach it is clamped to.
        let d_max = if self.reads_distances() {
            self.s * self.reach
        } else {
            self.s * (v_max as f64 + 0.75f64.sqrt())
        };
        let bound = 2.0 * self.k * count * d_max;
        acc.force_error_bound += bound;
        acc.torque_error_bound += bound * (r.length() + node.radius as f64);
        if value < 0 && from_parent.is_none() {
            return Ok(());
        }
        // The layers push unweighted (the paper's formula), the distances with the weights.
        let pick = |l: NodeLoad| {
            if self.reads_distances() {
                l.weighted
            } else {
                l.unweighted
            }
        };
        let load = match self.loads.get(j).map(|&l| pick(l)) {
            Some(push) if push.fits(node) => push,
            _ => pick(NodeLoad::from_cone(node)),
        };
        let d = if let Some((_, up)) = from_parent {
            let (depth, slope) = cur.distance_and_slope_in_brick(up);
            self.s * (depth + slope.dot(u - up)).clamp(0.0, self.reach)
        } else if self.reads_distances() {
            // Blended from the centre's own brick, not from an apron of up to eight (or the
            // sharp blend's 64 voxels), which in deep contact cost 4–40 µs an approximation,
            // all of them after the deadline. Any estimate within [0, reach] keeps the bound.
            self.s * cur.distance_in_brick(u)
        } else {
            self.penetration(value, v, u, self.rot * load.force().normalize_or_zero())
        };
        if d > 0.0 {
            // In the pointshell's frame and unscaled, like the points' sums (see
            // `test_points`): each point would push with w·d along its normal (w = 1 with the
            // layers). A load that fits its node has |Σ w·n| ≤ count and its points within the
            // sphere, so the bounds above hold.
            acc.force += load.force() * d;
            acc.torque += load.moment() * d;
            acc.energy += load.weight as f64 * d * d;
        }
        Ok(())
    }

    /// Breadth-first refinement until `deadline`, on the calling thread.
    ///
    /// Each level is planned before it starts ([`Frame::refinable`]): its first nodes are
    /// refined, as many as leave time to stand in for the rest and for the refined nodes'
    /// children; the rest is planned again with the pace measured meanwhile, up to
    /// [`PLANS_PER_LEVEL`] times. In case a plan was wrong, the clock is also read every [`CLOCK_EVERY`]
    /// nodes, before every leaf's points and before every node whose brick is not in the
    /// cursor's table (it may have to be decoded), and the level stops as soon as the time left
    /// no longer covers the stand-ins it would then owe.
    pub(super) fn walk_budgeted(&self, deadline: Instant, acc: &mut Contact) -> Result<(), StorageError> {
        // Each node with its parent, whose test read the parent's brick (see `approximate`).
        let mut level: Vec<(usize, Option<usize>)> = if self.nodes.is_empty() { vec![] } else { vec![(0, None)] };
        let mut next = Vec::new();
        let mut cur = self.voxmap.cursor();
        let mut pace = Pace::default();
        while !level.is_empty() {
            // Planned again as the pace is measured: a level is where the leaves begin, whose
            // points' pace was only guessed before it.
            let mut refined = 0;
            for _ in 0..PLANS_PER_LEVEL {
                let started = Instant::now();
                let left = deadline.saturating_duration_since(started).as_secs_f64();
                let plan = refined + self.refinable(&level[refined..], next.len(), left, &pace);
                if plan == refined {
                    break;
                }
                let stand_in_seconds = pace.node();
                let (mut point_seconds, mut points) = (0.0, 0);
                let from = refined;
                for &(i, _) in &level[from..plan] {
                    let node = &self.nodes[i];
                    let leaf = node.children().is_none();
                    // Stop while the time left still covers the stand-ins owed if it stops here.
                    let owed = (level.len() - refined + next.len()) as f64 * stand_in_seconds;
                    if ((refined - from) % CLOCK_EVERY == 0 || leaf || !self.at_hand(&cur, node))
                        && deadline.saturating_duration_since(Instant::now()).as_secs_f64() <= owed
                    {
                        break;
                    }
                    refined += 1;
                    acc.nodes_tested += 1;
                    if self.is_outside(&mut cur, node)? {
                        acc.nodes_culled += 1;
                        continue;
                    }
                    match node.children() {
                        Some([a, b]) => next.extend([(a, Some(i)), (b, Some(i))]),
                        None => {
                            let t = Instant::now();
                            self.test_points(&mut cur, node.points(), acc);
                            point_seconds += t.elapsed().as_secs_f64();
                            points += node.point_count as u64;
                        }
                    }
                }
                if refined > from {
                    pace.node_seconds += started.elapsed().as_secs_f64() - point_seconds;
                    pace.nodes += refined - from;
                    pace.point_seconds += point_seconds;
                    pace.points += points;
                }
                // The clock stopped this stretch short of its plan.
                if refined < plan {
                    break;
                }
            }
            for &(j, parent) in &level[refined..] {
                self.approximate(&mut cur, j, parent, acc)?;
            }
            std::mem::swap(&mut level, &mut next);
            next.clear();
        }
        cur.finish()
    }
}

/// Most pool threads a query wakes ahead of its tasks.
const WAKE_AHEAD: usize = 4;

/// Wake the pool's threads a query shares its tasks with ([`helpers`], at most
/// [`WAKE_AHEAD`]) now, so that they are up when the tasks come, with a job of nothing each:
/// in a servo loop they sleep between queries, and waking them took tens of µs on a VM, which
/// a query paid at the start of its parallel part. At 1 kHz on two cores this took the
/// built-in sweep's p99 from 614–680 µs to 464–571 (`docs/PERFORMANCE.md`, "Queries at a
/// servo loop's pace"); back to back the threads are awake and it costs about 0.4 µs.
fn wake_pool() {
    for _ in 0..helpers().min(WAKE_AHEAD) {
        rayon::spawn(|| {});
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::haptics::query::tests::{ball_shell, thick_box};
    use crate::haptics::query::ContactParams;
    use crate::Pose;

    /// The plan of a level against its definition: the most of the level's first nodes whose
    /// refinement (a node test, then a leaf's points or two children's stand-ins) and the
    /// others' stand-ins, with those already `owed`, fit in the time left.
    #[test]
    fn a_level_refines_the_most_nodes_that_fit() {
        let voxmap = thick_box();
        let shell = ball_shell(1.0, 12, 0.05);
        let pose = Pose::new([0.0, 0.0, 0.5], [1.0, 0.0, 0.0, 0.0]).unwrap();
        let frame = Frame::new(&voxmap, &shell, &pose, &ContactParams::default()).unwrap();
        // A level that mixes leaves and inner nodes, alternately (the plan does not ask which
        // depth its nodes are at).
        let inner = (0..frame.nodes.len()).filter(|&i| !frame.nodes[i].is_leaf()).skip(30);
        let leaves = (0..frame.nodes.len()).filter(|&i| frame.nodes[i].is_leaf());
        let level: Vec<(usize, Option<usize>)> = inner
            .zip(leaves)
            .take(40)
            .flat_map(|(a, b)| [(a, None), (b, None)])
            .collect();
        assert_eq!(level.len(), 80);
        for pace in [
            Pace {
                node_seconds: 0.0,
                nodes: 0,
                point_seconds: 0.0,
                points: 0,
            },
            Pace {
                node_seconds: 3e-6,
                nodes: 20,
                point_seconds: 4e-6,
                points: 1000,
            },
            Pace {
                node_seconds: 1e-9,
                nodes: 1000,
                point_seconds: 1e-9,
                points: 1000,
            },
        ] {
            let (node, point) = (pace.node(), pace.point());
            assert!(node >= MIN_NODE_SECONDS && point >= MIN_POINT_SECONDS);
            for owed in [0, 3, 40] {
                // What refining the first `k` costs, by its definition.
                let cost = |k: usize| -> f64 {
                    let refined: f64 = level[..k]
                        .iter()
                        .map(|&(i, _)| match frame.nodes[i].children() {
                            Some(_) => node + 2.0 * node,
                            None => node + frame.nodes[i].point_count as f64 * point,
                        })
                        .sum();
                    refined + (level.len() - k + owed) as f64 * node
                };
                let mut last = 0;
                for step in 0..200 {
                    let left = cost(level.len()) * 1.2 * step as f64 / 200.0;
                    let k = frame.refinable(&level, owed, left, &pace);
                    // The most that fit, give or take the rounding of the sums.
                    let most = |left: f64| (0..=level.len()).rev().find(|&k| cost(k) <= left).unwrap_or(0);
                    let (low, high) = (most(left * (1.0 - 1e-9)), most(left * (1.0 + 1e-9)));
                    assert!((low..=high).contains(&k), "left {left}: {k}, not in {low}..={high}");
                    assert!(k >= last, "more time, fewer nodes: {k} after {last}");
                    last = k;
                }
                assert_eq!(frame.refinable(&level, owed, f64::INFINITY, &pace), level.len());
                assert_eq!(frame.refinable(&level, owed, 0.0, &pace), 0);
            }
        }
    }
}
