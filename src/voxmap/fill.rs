//! Flood fill of the outside, brick by brick, never touching a dense grid.
//!
//! The outside is the set of non-surface voxels 6-connected to the grid's boundary (the paper's
//! flood fill). Bricks without surface voxels are open all through, so a whole run of them in
//! one (x, y) column of bricks is a single node, a *span*. Bricks with surface voxels are filled
//! voxel by voxel with bit masks. The graph therefore has one node per surface brick plus one
//! per gap between them in each column: its size follows the surface, not the volume.

use std::collections::VecDeque;

use super::mask::{Face, Mask512};

/// Which voxels the outside flood fill reached.
#[derive(Clone, Debug)]
pub struct Outside {
    nb: [u32; 3],
    /// For column `c = bx * ny + by`, its surface bricks are `col_start[c]..col_start[c + 1]`.
    col_start: Vec<u32>,
    /// Brick z of each surface brick.
    bz: Vec<u32>,
    /// Reached voxels of each surface brick.
    reached: Vec<Mask512>,
    /// Whether each gap was reached; gap `j` of column `c` has id `col_start[c] + c + j`.
    span_reached: Vec<bool>,
}

/// A node of the fill graph.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Node {
    /// A surface brick, by index.
    Brick(u32),
    /// A gap between surface bricks in a column, by id.
    Span(u32),
}

impl Outside {
    /// Flood the outside of `surface` (surface masks sorted by brick key, keys as in
    /// [`crate::grid::Grid::brick_key`]) in a grid of `nb` bricks, from voxel (0, 0, 0), which
    /// must not be a surface voxel.
    pub fn flood(nb: [u32; 3], surface: &[(u64, Mask512)]) -> Outside {
        let ncols = nb[0] as usize * nb[1] as usize;
        let mut col_start = vec![0u32; ncols + 1];
        let mut bz = Vec::with_capacity(surface.len());
        for &(key, _) in surface {
            let c = (key / nb[2] as u64) as usize;
            col_start[c + 1] += 1;
            bz.push((key % nb[2] as u64) as u32);
        }
        for c in 0..ncols {
            col_start[c + 1] += col_start[c];
        }
        let mut out = Outside {
            nb,
            col_start,
            bz,
            reached: vec![Mask512::EMPTY; surface.len()],
            span_reached: vec![false; surface.len() + ncols],
        };
        let walls: Vec<Mask512> = surface.iter().map(|s| s.1).collect();
        out.run(&walls);
        out
    }

    /// The node holding brick `(c, z)`: a surface brick or the gap containing it.
    fn node_at(&self, c: usize, z: u32) -> Node {
        let (s, e) = (self.col_start[c] as usize, self.col_start[c + 1] as usize);
        let j = self.bz[s..e].partition_point(|&b| b < z);
        if s + j < e && self.bz[s + j] == z {
            Node::Brick((s + j) as u32)
        } else {
            Node::Span((s + c + j) as u32)
        }
    }

    /// Column and z range `[z0, z1]` of gap `id`; `None` if the gap is empty.
    fn span_range(&self, id: u32) -> Option<(usize, u32, u32)> {
        let id = id as usize;
        let c = self.column_of_gap(id);
        let s = self.col_start[c] as usize;
        let e = self.col_start[c + 1] as usize;
        let j = id - s - c;
        let z0 = if j == 0 { 0 } else { self.bz[s + j - 1] + 1 };
        let z1 = if s + j < e { self.bz[s + j] } else { self.nb[2] };
        (z1 > z0).then(|| (c, z0, z1 - 1))
    }

    /// The column of gap `id`: the largest `c` with `col_start[c] + c <= id`, as column `c`
    /// holds gap ids `col_start[c] + c ..= col_start[c + 1] + c`.
    fn column_of_gap(&self, id: usize) -> usize {
        let n = self.col_start.len() - 1;
        let (mut lo, mut hi) = (0usize, n);
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if self.col_start[mid] as usize + mid <= id {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    }

    fn column_xy(&self, c: usize) -> (u32, u32) {
        ((c / self.nb[1] as usize) as u32, (c % self.nb[1] as usize) as u32)
    }

    /// The column beside `c` across `face` (x or y), if inside the grid.
    fn side_column(&self, c: usize, face: Face) -> Option<usize> {
        let (x, y) = self.column_xy(c);
        let (x, y) = match (face.axis, face.side) {
            (0, 0) => (x.checked_sub(1)?, y),
            (0, _) => (x + 1, y),
            (1, 0) => (x, y.checked_sub(1)?),
            _ => (x, y + 1),
        };
        (x < self.nb[0] && y < self.nb[1]).then(|| x as usize * self.nb[1] as usize + y as usize)
    }

    fn run(&mut self, walls: &[Mask512]) {
        let mut queue = VecDeque::new();
        let mut queued = vec![false; walls.len()];
        match self.node_at(0, 0) {
            Node::Span(id) => {
                self.span_reached[id as usize] = true;
                queue.push_back(Node::Span(id));
            }
            Node::Brick(i) => {
                let mut seed = Mask512::EMPTY;
                seed.set(0);
                self.seed_brick(i, seed, walls, &mut queue, &mut queued);
            }
        }
        while let Some(node) = queue.pop_front() {
            match node {
                Node::Span(id) => self.visit_span(id, walls, &mut queue, &mut queued),
                Node::Brick(i) => {
                    queued[i as usize] = false;
                    self.visit_brick(i, walls, &mut queue, &mut queued);
                }
            }
        }
    }

    fn seed_brick(
        &mut self,
        i: u32,
        seed: Mask512,
        walls: &[Mask512],
        queue: &mut VecDeque<Node>,
        queued: &mut [bool],
    ) {
        let fresh = seed.and_not(&walls[i as usize]).and_not(&self.reached[i as usize]);
        if fresh.is_empty() {
            return;
        }
        self.reached[i as usize] = self.reached[i as usize].or(&fresh);
        if !queued[i as usize] {
            queued[i as usize] = true;
            queue.push_back(Node::Brick(i));
        }
    }

    fn reach_span(&mut self, id: u32, queue: &mut VecDeque<Node>) {
        if !self.span_reached[id as usize] {
            self.span_reached[id as usize] = true;
            queue.push_back(Node::Span(id));
        }
    }

    /// A reached span opens every face it shares with its neighbours.
    fn visit_span(&mut self, id: u32, walls: &[Mask512], queue: &mut VecDeque<Node>, queued: &mut [bool]) {
        let Some((c, z0, z1)) = self.span_range(id) else {
            return;
        };
        let (s, e) = (self.col_start[c] as usize, self.col_start[c + 1] as usize);
        let j = id as usize - s - c;
        // The surface bricks capping the span below and above.
        if j > 0 {
            let f = Face { axis: 2, side: 1 };
            self.seed_brick((s + j - 1) as u32, Mask512::face(f), walls, queue, queued);
        }
        if s + j < e {
            let f = Face { axis: 2, side: 0 };
            self.seed_brick((s + j) as u32, Mask512::face(f), walls, queue, queued);
        }
        // Everything beside it in the four neighbouring columns, over z0..=z1.
        for face in [
            Face { axis: 0, side: 0 },
            Face { axis: 0, side: 1 },
            Face { axis: 1, side: 0 },
            Face { axis: 1, side: 1 },
        ] {
            let Some(nc) = self.side_column(c, face) else {
                continue;
            };
            let (ns, ne) = (self.col_start[nc] as usize, self.col_start[nc + 1] as usize);
            let mut k = ns + self.bz[ns..ne].partition_point(|&b| b < z0);
            // The gap just below brick k (gap index k - ns) may overlap [z0, z1].
            loop {
                let gap_lo = if k == ns { 0 } else { self.bz[k - 1] + 1 };
                let gap_hi = if k < ne {
                    self.bz[k] as i64 - 1
                } else {
                    self.nb[2] as i64 - 1
                };
                if gap_hi >= gap_lo as i64 && gap_hi >= z0 as i64 && (gap_lo as i64) <= z1 as i64 {
                    self.reach_span((k + nc) as u32, queue);
                }
                if k >= ne || self.bz[k] > z1 {
                    break;
                }
                self.seed_brick(k as u32, Mask512::face(face.opposite()), walls, queue, queued);
                k += 1;
            }
        }
    }

    /// Fill a surface brick from its reached voxels, then pass what reaches its faces on.
    fn visit_brick(&mut self, i: u32, walls: &[Mask512], queue: &mut VecDeque<Node>, queued: &mut [bool]) {
        let open = Mask512::FULL.and_not(&walls[i as usize]);
        let filled = self.reached[i as usize].flood_within(&open);
        self.reached[i as usize] = filled;
        let col = self.column_of_brick(i as usize);
        let z = self.bz[i as usize];
        for face in Face::ALL {
            let out = filled.across(face);
            if out.is_empty() {
                continue;
            }
            let target = match (face.axis, face.side) {
                (2, 0) if z == 0 => None,
                (2, 0) => Some(self.node_at(col, z - 1)),
                (2, _) if z + 1 >= self.nb[2] => None,
                (2, _) => Some(self.node_at(col, z + 1)),
                _ => self.side_column(col, face).map(|nc| self.node_at(nc, z)),
            };
            match target {
                Some(Node::Span(id)) => self.reach_span(id, queue),
                Some(Node::Brick(j)) => self.seed_brick(j, out, walls, queue, queued),
                None => {}
            }
        }
    }

    fn column_of_brick(&self, i: usize) -> usize {
        self.col_start.partition_point(|&s| s as usize <= i) - 1
    }

    /// Voxels of surface brick `i` (index into the surface list) that are outside.
    pub fn reached_voxels(&self, i: usize) -> Mask512 {
        self.reached[i]
    }

    /// Whether the brick at `key`, which has no surface voxels, is outside (all its voxels alike).
    pub fn empty_brick_is_outside(&self, key: u64) -> bool {
        let c = (key / self.nb[2] as u64) as usize;
        let z = (key % self.nb[2] as u64) as u32;
        match self.node_at(c, z) {
            Node::Span(id) => self.span_reached[id as usize],
            // A surface brick has no single answer; callers ask only about empty bricks.
            Node::Brick(_) => false,
        }
    }

    /// Ranges of brick keys `[start, end)` of empty bricks that the fill did not reach: the
    /// enclosed inside, in key order.
    pub fn enclosed_spans(&self) -> impl Iterator<Item = (u64, u64)> + '_ {
        let nz = self.nb[2] as u64;
        (0..self.span_reached.len())
            .filter(|&id| !self.span_reached[id])
            .filter_map(move |id| {
                let (c, z0, z1) = self.span_range(id as u32)?;
                Some((c as u64 * nz + z0 as u64, c as u64 * nz + z1 as u64 + 1))
            })
    }
}
