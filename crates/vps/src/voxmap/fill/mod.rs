//! Flood fill of the outside, brick by brick, never touching a dense grid.
//!
//! The outside is the set of non-surface voxels 6-connected to the grid's boundary (the paper's
//! flood fill). Bricks without surface voxels are open all through, so a whole run of them in
//! one (x, y) column of bricks is a single node, a *span*. Bricks with surface voxels are filled
//! voxel by voxel with bit masks. The graph therefore has one node per surface brick plus one
//! per gap between them in each column: its size follows the surface, not the volume.
//!
//! For grids too large to hold at once, [`Components`] labels the open voxels of one slab of
//! bricks along x; the caller unites labels across slab faces ([`Components::unite_across`])
//! and turns each slab's labels into its [`Outside`] ([`Components::into_outside`]).

use std::collections::VecDeque;

use super::mask::{Face, Mask512};
use crate::grid::split_voxel;

mod components;

pub(crate) use components::UnionFind;
pub use components::{Components, FaceItem, XFace};

/// The four faces that lead to a neighbouring column.
const SIDES: [Face; 4] = [
    Face { axis: 0, side: 0 },
    Face { axis: 0, side: 1 },
    Face { axis: 1, side: 0 },
    Face { axis: 1, side: 1 },
];

/// The sparse graph shared by the fill and the labelling: surface bricks by column, and the
/// gaps between them.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Columns {
    nb: [u32; 3],
    /// For column `c = bx * ny + by`, its surface bricks are `col_start[c]..col_start[c + 1]`.
    col_start: Vec<u32>,
    /// Brick z of each surface brick.
    bz: Vec<u32>,
}

/// A node of the graph.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Node {
    /// A surface brick, by index.
    Brick(u32),
    /// A gap between surface bricks in a column, by id.
    Span(u32),
}

/// A non-empty gap: bricks `z0..z1` of column `col`, between the surface bricks `below` and
/// `above` (if any).
#[derive(Clone, Copy, Debug)]
struct Gap {
    id: u32,
    col: usize,
    z0: u32,
    z1: u32,
    below: Option<u32>,
    above: Option<u32>,
}

impl Columns {
    fn new(nb: [u32; 3], surface: &[(u64, Mask512)]) -> Columns {
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
        Columns { nb, col_start, bz }
    }

    fn ncols(&self) -> usize {
        self.col_start.len() - 1
    }

    /// Gap ids run over `0..gap_count()`; gap `j` of column `c` has id `col_start[c] + c + j`.
    fn gap_count(&self) -> usize {
        self.bz.len() + self.ncols()
    }

    fn bricks_of(&self, c: usize) -> (usize, usize) {
        (self.col_start[c] as usize, self.col_start[c + 1] as usize)
    }

    /// The node holding brick `(c, z)`: a surface brick or the gap containing it.
    fn node_at(&self, c: usize, z: u32) -> Node {
        let (s, e) = self.bricks_of(c);
        let j = self.bz[s..e].partition_point(|&b| b < z);
        if s + j < e && self.bz[s + j] == z {
            Node::Brick((s + j) as u32)
        } else {
            Node::Span((s + c + j) as u32)
        }
    }

    /// Gap `j` of column `c`; `None` if it holds no brick.
    fn gap_in(&self, c: usize, j: usize) -> Option<Gap> {
        let (s, e) = self.bricks_of(c);
        let z0 = if j == 0 { 0 } else { self.bz[s + j - 1] + 1 };
        let z1 = if s + j < e { self.bz[s + j] } else { self.nb[2] };
        (z1 > z0).then(|| Gap {
            id: (s + c + j) as u32,
            col: c,
            z0,
            z1,
            below: (j > 0).then(|| (s + j - 1) as u32),
            above: (s + j < e).then_some((s + j) as u32),
        })
    }

    /// Gap `id`; `None` if it holds no brick.
    fn gap(&self, id: u32) -> Option<Gap> {
        let c = self.column_of_gap(id as usize);
        self.gap_in(c, id as usize - self.col_start[c] as usize - c)
    }

    /// The non-empty gaps in id order.
    fn gaps(&self) -> impl Iterator<Item = Gap> + '_ {
        (0..self.ncols()).flat_map(move |c| {
            let (s, e) = self.bricks_of(c);
            (0..=e - s).filter_map(move |j| self.gap_in(c, j))
        })
    }

    /// The column of gap `id`: the largest `c` with `col_start[c] + c <= id`, as column `c`
    /// holds gap ids `col_start[c] + c ..= col_start[c + 1] + c`.
    fn column_of_gap(&self, id: usize) -> usize {
        let (mut lo, mut hi) = (0usize, self.ncols());
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

    /// The neighbour of surface brick `i` (in column `c`) across `face`, if inside the grid.
    fn neighbour(&self, c: usize, i: usize, face: Face) -> Option<Node> {
        let z = self.bz[i];
        match (face.axis, face.side) {
            (2, 0) => z.checked_sub(1).map(|z| self.node_at(c, z)),
            (2, _) => (z + 1 < self.nb[2]).then(|| self.node_at(c, z + 1)),
            _ => self.side_column(c, face).map(|nc| self.node_at(nc, z)),
        }
    }

    /// Call `f(node, z0, z1)` for each node of column `c` holding some of bricks `z0..z1`, in z
    /// order, with the node's own brick range: walking a column beside a span costs what
    /// overlaps it, not a search per brick.
    fn items_in(&self, c: usize, z0: u32, z1: u32, mut f: impl FnMut(Node, u32, u32)) {
        let (s, e) = self.bricks_of(c);
        let mut k = s + self.bz[s..e].partition_point(|&b| b < z0);
        // The gap just below brick k (gap index k - s) may overlap z0..z1.
        loop {
            let gap_lo = if k == s { 0 } else { self.bz[k - 1] + 1 };
            let gap_hi = if k < e { self.bz[k] } else { self.nb[2] };
            if gap_hi > gap_lo && gap_hi > z0 && gap_lo < z1 {
                f(Node::Span((k + c) as u32), gap_lo, gap_hi);
            }
            if k >= e || self.bz[k] >= z1 {
                break;
            }
            f(Node::Brick(k as u32), self.bz[k], self.bz[k] + 1);
            k += 1;
        }
    }
}

/// Which voxels the outside flood fill reached.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Outside {
    cols: Columns,
    /// Reached voxels of each surface brick.
    reached: Vec<Mask512>,
    /// Whether each gap was reached, by gap id.
    span_reached: Vec<bool>,
}

/// The state of one flood fill.
struct Flood<'a> {
    cols: &'a Columns,
    walls: &'a [Mask512],
    reached: Vec<Mask512>,
    span_reached: Vec<bool>,
    queue: VecDeque<Node>,
    queued: Vec<bool>,
}

impl Outside {
    /// Flood the outside of `surface` (surface masks sorted by brick key, keys as in
    /// [`crate::grid::Grid::brick_key`]) in a grid of `nb` bricks, from voxel (0, 0, 0), which
    /// must not be a surface voxel.
    pub fn flood(nb: [u32; 3], surface: &[(u64, Mask512)]) -> Outside {
        let cols = Columns::new(nb, surface);
        let walls: Vec<Mask512> = surface.iter().map(|s| s.1).collect();
        let mut f = Flood {
            cols: &cols,
            walls: &walls,
            reached: vec![Mask512::EMPTY; surface.len()],
            span_reached: vec![false; cols.gap_count()],
            queue: VecDeque::new(),
            queued: vec![false; surface.len()],
        };
        f.run();
        let Flood {
            reached, span_reached, ..
        } = f;
        Outside {
            cols,
            reached,
            span_reached,
        }
    }

    /// Voxels of surface brick `i` (index into the surface list) that are outside.
    pub fn reached_voxels(&self, i: usize) -> Mask512 {
        self.reached[i]
    }

    /// The outside voxels of the surface brick at `key`; `None` if that brick has no surface
    /// voxels (or lies beyond the grid).
    pub fn outside_voxels_of(&self, key: u64) -> Option<Mask512> {
        let nz = self.cols.nb[2] as u64;
        let c = key / nz;
        if c >= self.cols.ncols() as u64 {
            return None;
        }
        match self.cols.node_at(c as usize, (key % nz) as u32) {
            Node::Brick(i) => Some(self.reached[i as usize]),
            Node::Span(_) => None,
        }
    }

    /// Whether the brick at `key`, which has no surface voxels, is outside (all its voxels alike).
    pub fn empty_brick_is_outside(&self, key: u64) -> bool {
        let c = (key / self.cols.nb[2] as u64) as usize;
        let z = (key % self.cols.nb[2] as u64) as u32;
        match self.cols.node_at(c, z) {
            Node::Span(id) => self.span_reached[id as usize],
            // A surface brick has no single answer; callers ask only about empty bricks.
            Node::Brick(_) => false,
        }
    }

    /// Ranges of brick keys `[start, end)` of empty bricks that the fill did not reach: the
    /// enclosed inside, in key order.
    pub fn enclosed_spans(&self) -> impl Iterator<Item = (u64, u64)> + '_ {
        let nz = self.cols.nb[2] as u64;
        self.cols
            .gaps()
            .filter(|g| !self.span_reached[g.id as usize])
            .map(move |g| (g.col as u64 * nz + g.z0 as u64, g.col as u64 * nz + g.z1 as u64))
    }
}

impl Flood<'_> {
    fn run(&mut self) {
        match self.cols.node_at(0, 0) {
            Node::Span(id) => self.reach_span(id),
            Node::Brick(i) => {
                let mut seed = Mask512::EMPTY;
                seed.set(0);
                self.seed_brick(i, seed);
            }
        }
        while let Some(node) = self.queue.pop_front() {
            match node {
                Node::Span(id) => self.visit_span(id),
                Node::Brick(i) => {
                    self.queued[i as usize] = false;
                    self.visit_brick(i);
                }
            }
        }
    }

    fn seed_brick(&mut self, i: u32, seed: Mask512) {
        let i = i as usize;
        let fresh = seed.and_not(&self.walls[i]).and_not(&self.reached[i]);
        if fresh.is_empty() {
            return;
        }
        self.reached[i] = self.reached[i].or(&fresh);
        if !self.queued[i] {
            self.queued[i] = true;
            self.queue.push_back(Node::Brick(i as u32));
        }
    }

    fn reach_span(&mut self, id: u32) {
        if !self.span_reached[id as usize] {
            self.span_reached[id as usize] = true;
            self.queue.push_back(Node::Span(id));
        }
    }

    /// A reached span opens every face it shares with its neighbours.
    fn visit_span(&mut self, id: u32) {
        let cols = self.cols;
        let Some(g) = cols.gap(id) else {
            return;
        };
        if let Some(b) = g.below {
            self.seed_brick(b, Mask512::face(Face { axis: 2, side: 1 }));
        }
        if let Some(a) = g.above {
            self.seed_brick(a, Mask512::face(Face { axis: 2, side: 0 }));
        }
        for face in SIDES {
            let Some(nc) = cols.side_column(g.col, face) else {
                continue;
            };
            cols.items_in(nc, g.z0, g.z1, |node, _, _| match node {
                Node::Span(s) => self.reach_span(s),
                Node::Brick(k) => self.seed_brick(k, Mask512::face(face.opposite())),
            });
        }
    }

    /// Fill a surface brick from its reached voxels, then pass what reaches its faces on.
    fn visit_brick(&mut self, i: u32) {
        let open = Mask512::FULL.and_not(&self.walls[i as usize]);
        let filled = self.reached[i as usize].flood_within(&open);
        self.reached[i as usize] = filled;
        let col = self.cols.col_start.partition_point(|&s| s <= i) - 1;
        for face in Face::ALL {
            let out = filled.across(face);
            if out.is_empty() {
                continue;
            }
            match self.cols.neighbour(col, i as usize, face) {
                Some(Node::Span(id)) => self.reach_span(id),
                Some(Node::Brick(j)) => self.seed_brick(j, out),
                None => {}
            }
        }
    }
}

#[cfg(test)]
mod tests;
