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
mod tests {
    use super::*;
    use crate::grid::local_index;

    /// SplitMix64: a seeded generator so every case can be replayed.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^ (z >> 31)
        }

        /// Uniform in `lo..hi`.
        fn range(&mut self, lo: u32, hi: u32) -> u32 {
            lo + (self.next() % (hi - lo) as u64) as u32
        }

        fn chance(&mut self, p: f64) -> bool {
            (self.next() >> 11) as f64 / (1u64 << 53) as f64 > 1.0 - p
        }
    }

    /// A dense grid of walls, in voxels.
    struct Dense {
        nb: [u32; 3],
        wall: Vec<bool>,
    }

    impl Dense {
        fn new(nb: [u32; 3]) -> Dense {
            let n = nb.iter().map(|&b| 8 * b as usize).product();
            Dense {
                nb,
                wall: vec![false; n],
            }
        }

        fn dims(&self) -> [u32; 3] {
            self.nb.map(|b| 8 * b)
        }

        fn index(&self, v: [u32; 3]) -> usize {
            let d = self.dims();
            (v[0] as usize * d[1] as usize + v[1] as usize) * d[2] as usize + v[2] as usize
        }

        fn set(&mut self, v: [u32; 3], wall: bool) {
            let i = self.index(v);
            self.wall[i] = wall;
        }

        /// Set every voxel of the box `lo..=hi`.
        fn fill_box(&mut self, lo: [u32; 3], hi: [u32; 3], wall: bool) {
            for x in lo[0]..=hi[0] {
                for y in lo[1]..=hi[1] {
                    for z in lo[2]..=hi[2] {
                        self.set([x, y, z], wall);
                    }
                }
            }
        }

        fn voxels(&self) -> impl Iterator<Item = [u32; 3]> {
            let d = self.dims();
            (0..d[0]).flat_map(move |x| (0..d[1]).flat_map(move |y| (0..d[2]).map(move |z| [x, y, z])))
        }

        /// The surface list, as [`Outside::flood`] takes it.
        fn surface(&self) -> Vec<(u64, Mask512)> {
            let nb = self.nb;
            let mut out = Vec::new();
            for bx in 0..nb[0] {
                for by in 0..nb[1] {
                    for bz in 0..nb[2] {
                        let mut m = Mask512::EMPTY;
                        for (x, y, z) in (0..8).flat_map(|x| (0..8).flat_map(move |y| (0..8).map(move |z| (x, y, z)))) {
                            if self.wall[self.index([bx * 8 + x, by * 8 + y, bz * 8 + z])] {
                                m.set(local_index(x, y, z));
                            }
                        }
                        if !m.is_empty() {
                            out.push((((bx * nb[1] + by) * nb[2] + bz) as u64, m));
                        }
                    }
                }
            }
            out
        }

        /// Plain BFS labels of the open voxels (`u32::MAX` on walls).
        fn labels(&self) -> Vec<u32> {
            let d = self.dims();
            let mut label = vec![u32::MAX; self.wall.len()];
            let mut next = 0;
            let mut queue = VecDeque::new();
            for v in self.voxels() {
                let i = self.index(v);
                if self.wall[i] || label[i] != u32::MAX {
                    continue;
                }
                label[i] = next;
                queue.push_back(v);
                while let Some(u) = queue.pop_front() {
                    for a in 0..3 {
                        for step in [-1i64, 1] {
                            let c = u[a] as i64 + step;
                            if c < 0 || c >= d[a] as i64 {
                                continue;
                            }
                            let mut w = u;
                            w[a] = c as u32;
                            let j = self.index(w);
                            if !self.wall[j] && label[j] == u32::MAX {
                                label[j] = next;
                                queue.push_back(w);
                            }
                        }
                    }
                }
                next += 1;
            }
            label
        }
    }

    /// A random scene: noise of varied density in some bricks, walls with few holes (closed
    /// pockets), hollow boxes, and solid blocks with a winding channel carved through.
    fn random_dense(rng: &mut Rng, min_nx: u32) -> Dense {
        let nb = [rng.range(min_nx, 5), rng.range(1, 4), rng.range(1, 6)];
        let mut g = Dense::new(nb);
        let d = g.dims();
        let density = [0.02, 0.1, 0.3, 0.5, 0.7][rng.range(0, 5) as usize];
        let busy = rng.range(0, 4) as f64 / 4.0;
        for bx in 0..nb[0] {
            for by in 0..nb[1] {
                for bz in 0..nb[2] {
                    if !rng.chance(busy) {
                        continue;
                    }
                    for x in 0..8 {
                        for y in 0..8 {
                            for z in 0..8 {
                                if rng.chance(density) {
                                    g.set([bx * 8 + x, by * 8 + y, bz * 8 + z], true);
                                }
                            }
                        }
                    }
                }
            }
        }
        // Whole walls across the grid, with a few holes or none.
        for _ in 0..rng.range(0, 3) {
            let a = rng.range(0, 3) as usize;
            let at = rng.range(0, d[a]);
            let mut lo = [0; 3];
            let mut hi = d.map(|n| n - 1);
            lo[a] = at;
            hi[a] = at;
            g.fill_box(lo, hi, true);
            for _ in 0..rng.range(0, 3) {
                let mut v = [0; 3].map(|_| 0);
                for (b, c) in v.iter_mut().enumerate() {
                    *c = if b == a { at } else { rng.range(0, d[b]) };
                }
                g.set(v, false);
            }
        }
        // Hollow boxes, sometimes with one hole.
        for _ in 0..rng.range(0, 3) {
            let lo: [u32; 3] = std::array::from_fn(|a| rng.range(0, d[a] - 2));
            let hi: [u32; 3] = std::array::from_fn(|a| rng.range(lo[a] + 2, d[a].min(lo[a] + 14)));
            g.fill_box(lo, hi, true);
            g.fill_box(lo.map(|c| c + 1), hi.map(|c| c - 1), false);
            if rng.chance(0.5) {
                g.set([lo[0], (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2], false);
            }
        }
        // A solid block with a random walk carved through it.
        if rng.chance(0.5) {
            let lo: [u32; 3] = std::array::from_fn(|a| rng.range(0, d[a] / 2));
            let hi: [u32; 3] = std::array::from_fn(|a| rng.range(d[a] / 2, d[a]));
            g.fill_box(lo, hi, true);
            let mut v: [u32; 3] = std::array::from_fn(|a| rng.range(lo[a], hi[a] + 1));
            for _ in 0..rng.range(20, 600) {
                g.set(v, false);
                let a = rng.range(0, 3) as usize;
                let step = if rng.chance(0.5) { 1 } else { -1 };
                let c = v[a] as i64 + step;
                if c >= lo[a] as i64 && c <= hi[a] as i64 {
                    v[a] = c as u32;
                }
            }
        }
        g.set([0, 0, 0], false);
        g
    }

    /// Whether voxel `v` is outside by `o`'s public answers.
    fn is_outside(o: &Outside, nb: [u32; 3], v: [u32; 3]) -> bool {
        let (b, local) = split_voxel(v);
        let key = ((b[0] * nb[1] + b[1]) * nb[2] + b[2]) as u64;
        match o.outside_voxels_of(key) {
            Some(m) => m.get(local),
            None => o.empty_brick_is_outside(key),
        }
    }

    /// The same partition of the open voxels, whatever the numbering.
    fn assert_same_partition(g: &Dense, comps: &Components, case: u64) {
        let dense = g.labels();
        let classes = dense.iter().filter(|&&l| l != u32::MAX).max().map_or(0, |&m| m + 1);
        assert_eq!(comps.count(), classes, "case {case}");
        let mut to_comp = vec![u32::MAX; classes as usize];
        let mut to_dense = vec![u32::MAX; classes as usize];
        for v in g.voxels() {
            let dl = dense[g.index(v)];
            let cl = comps.label_of(v);
            if dl == u32::MAX {
                assert_eq!(cl, None, "case {case} voxel {v:?}");
                continue;
            }
            let cl = cl.unwrap_or_else(|| panic!("case {case}: open voxel {v:?} unlabelled"));
            assert!(cl < comps.count());
            if to_comp[dl as usize] == u32::MAX {
                to_comp[dl as usize] = cl;
            }
            if to_dense[cl as usize] == u32::MAX {
                to_dense[cl as usize] = dl;
            }
            assert_eq!(to_comp[dl as usize], cl, "case {case} voxel {v:?}");
            assert_eq!(to_dense[cl as usize], dl, "case {case} voxel {v:?}");
        }
    }

    #[test]
    fn label_matches_dense_bfs() {
        for case in 0..300 {
            let mut rng = Rng(case);
            let g = random_dense(&mut rng, 1);
            let surface = g.surface();
            let comps = Components::label(g.nb, &surface);
            assert_same_partition(&g, &comps, case);
            // Deterministic.
            let again = Components::label(g.nb, &surface);
            assert_eq!(again.span_label, comps.span_label);
            assert_eq!(again.part_label, comps.part_label);
        }
    }

    #[test]
    fn flood_matches_dense_bfs() {
        for case in 0..200 {
            let mut rng = Rng(1000 + case);
            let g = random_dense(&mut rng, 1);
            let o = Outside::flood(g.nb, &g.surface());
            let dense = g.labels();
            for v in g.voxels() {
                let want = dense[g.index(v)] == dense[0];
                assert_eq!(is_outside(&o, g.nb, v), want, "case {case} voxel {v:?}");
            }
        }
    }

    #[test]
    fn into_outside_matches_flood() {
        for case in 0..300 {
            let mut rng = Rng(2000 + case);
            let g = random_dense(&mut rng, 1);
            let surface = g.surface();
            let flood = Outside::flood(g.nb, &surface);
            let comps = Components::label(g.nb, &surface);
            let seed = comps.label_of([0, 0, 0]);
            assert!(seed.is_some());
            let o = comps.into_outside(|l| Some(l) == seed);
            assert_eq!(
                o.enclosed_spans().collect::<Vec<_>>(),
                flood.enclosed_spans().collect::<Vec<_>>()
            );
            let nbricks = g.nb.iter().map(|&n| n as u64).product::<u64>();
            for key in 0..nbricks {
                assert_eq!(o.outside_voxels_of(key), flood.outside_voxels_of(key), "case {case}");
                if o.outside_voxels_of(key).is_none() {
                    assert_eq!(
                        o.empty_brick_is_outside(key),
                        flood.empty_brick_is_outside(key),
                        "case {case}"
                    );
                }
            }
            for i in 0..surface.len() {
                assert_eq!(o.reached_voxels(i), flood.reached_voxels(i), "case {case}");
            }
            assert_eq!(o, flood, "case {case}");
        }
    }

    /// Bricks `a..b` along x of a grid's surface list, keys re-based to the slab.
    fn slab(nb: [u32; 3], surface: &[(u64, Mask512)], a: u32, b: u32) -> ([u32; 3], Vec<(u64, Mask512)>) {
        let plane = nb[1] as u64 * nb[2] as u64;
        let (lo, hi) = (a as u64 * plane, b as u64 * plane);
        let s = surface
            .iter()
            .filter(|s| (lo..hi).contains(&s.0))
            .map(|&(k, m)| (k - lo, m))
            .collect();
        ([b - a, nb[1], nb[2]], s)
    }

    /// Label each slab, unite across boundaries, and check every voxel against the whole
    /// grid's flood.
    fn check_slabs(g: &Dense, cuts: &[u32], case: &str) {
        let nb = g.nb;
        let surface = g.surface();
        let flood = Outside::flood(nb, &surface);
        let slabs: Vec<([u32; 3], Components)> = cuts
            .windows(2)
            .map(|w| {
                let (snb, s) = slab(nb, &surface, w[0], w[1]);
                (snb, Components::label(snb, &s))
            })
            .collect();
        let mut offset = vec![0u32];
        for s in &slabs {
            offset.push(offset.last().unwrap() + s.1.count());
        }
        let mut uf = UnionFind::new(*offset.last().unwrap() as usize);
        for k in 0..slabs.len() - 1 {
            let (high, low) = (slabs[k].1.x_face(1), slabs[k + 1].1.x_face(0));
            Components::unite_across(&high, &low, |a, b| uf.union(offset[k] + a, offset[k + 1] + b));
        }
        let seed = slabs[0].1.label_of([0, 0, 0]).expect("voxel (0, 0, 0) is open");
        let root = uf.find(seed);
        let mut enclosed = Vec::new();
        for (k, (snb, comps)) in slabs.into_iter().enumerate() {
            let outside: Vec<bool> = (0..comps.count()).map(|l| uf.find(offset[k] + l) == root).collect();
            let o = comps.into_outside(|l| outside[l as usize]);
            let base = cuts[k] as u64 * nb[1] as u64 * nb[2] as u64;
            enclosed.extend(o.enclosed_spans().map(|(s, e)| (s + base, e + base)));
            for v in g.voxels().filter(|v| (cuts[k] * 8..cuts[k + 1] * 8).contains(&v[0])) {
                let local = [v[0] - cuts[k] * 8, v[1], v[2]];
                assert_eq!(
                    is_outside(&o, snb, local),
                    is_outside(&flood, nb, v),
                    "{case}: voxel {v:?}"
                );
            }
        }
        assert_eq!(enclosed, flood.enclosed_spans().collect::<Vec<_>>(), "{case}");
    }

    #[test]
    fn slabs_match_whole_grid_flood() {
        for case in 0..300 {
            let mut rng = Rng(3000 + case);
            let g = random_dense(&mut rng, 2);
            let nx = g.nb[0];
            let cuts = if nx >= 3 && rng.chance(0.5) {
                let a = rng.range(1, nx - 1);
                vec![0, a, rng.range(a + 1, nx), nx]
            } else {
                vec![0, rng.range(1, nx), nx]
            };
            check_slabs(&g, &cuts, &format!("case {case}, cuts {cuts:?}"));
        }
    }

    /// The outside leaves slab 0 through open air, enters a solid block in slab 2, and comes back
    /// through the block to a chamber in slab 0 that nothing in slab 0 or 1 connects to the air:
    /// a single forward sweep over the slabs would leave that chamber inside.
    #[test]
    fn serpentine_through_slabs_matches_flood() {
        let mut g = Dense::new([3, 3, 3]);
        // The block fills brick y = 1 across the whole grid: air at y < 8 and at y >= 16.
        g.fill_box([0, 8, 0], [23, 15, 23], true);
        // Down into the block in slab 2, along it at y = 10 back to x = 3, into a chamber.
        g.fill_box([20, 8, 4], [20, 10, 4], false);
        g.fill_box([3, 10, 4], [20, 10, 4], false);
        g.fill_box([1, 10, 3], [5, 13, 6], false);
        // Sealed chambers in slabs 0 and 1.
        g.fill_box([1, 10, 14], [5, 13, 20], false);
        g.fill_box([9, 12, 12], [14, 14, 20], false);
        let flood = Outside::flood(g.nb, &g.surface());
        assert!(is_outside(&flood, g.nb, [2, 12, 5]));
        assert!(!is_outside(&flood, g.nb, [2, 12, 15]));
        assert!(!is_outside(&flood, g.nb, [10, 13, 15]));
        assert!(!is_outside(&flood, g.nb, [0, 20, 0]));
        // Slab 0 alone does not join its chamber to the air.
        let (snb, s) = slab(g.nb, &g.surface(), 0, 1);
        let c = Components::label(snb, &s);
        assert_ne!(c.label_of([2, 12, 5]), c.label_of([0, 0, 0]));
        check_slabs(&g, &[0, 1, 2, 3], "serpentine");
        check_slabs(&g, &[0, 2, 3], "serpentine, two slabs");
    }

    /// The face holds, for each (y, z), the label of the face voxel there.
    #[test]
    fn x_face_matches_label_of() {
        for case in 0..100 {
            let mut rng = Rng(4000 + case);
            let g = random_dense(&mut rng, 1);
            let comps = Components::label(g.nb, &g.surface());
            let d = g.dims();
            for side in 0..2 {
                let face = comps.x_face(side);
                let x = if side == 0 { 0 } else { d[0] - 1 };
                for y in 0..d[1] {
                    for z in 0..d[2] {
                        let item = face
                            .column(y / 8)
                            .iter()
                            .find(|it| (it.z_range().0..it.z_range().1).contains(&(z / 8)));
                        let got = match item {
                            Some(FaceItem::Span { label, .. }) => Some(*label),
                            Some(FaceItem::Brick { parts, .. }) => {
                                let bit = 1u64 << ((z % 8) * 8 + y % 8);
                                let hits: Vec<u32> = parts.iter().filter(|p| p.1 & bit != 0).map(|p| p.0).collect();
                                assert!(hits.len() <= 1, "case {case}");
                                hits.first().copied()
                            }
                            None => None,
                        };
                        assert_eq!(
                            got,
                            comps.label_of([x, y, z]),
                            "case {case} side {side} voxel {:?}",
                            [x, y, z]
                        );
                    }
                }
            }
        }
    }

    /// Mostly empty space costs one item per column, not one per brick.
    #[test]
    fn x_face_is_compact() {
        let mut g = Dense::new([2, 3, 5]);
        g.set([0, 9, 20], true);
        let comps = Components::label(g.nb, &g.surface());
        assert_eq!(comps.count(), 1);
        let face = comps.x_face(0);
        let lens: Vec<usize> = (0..3).map(|by| face.column(by).len()).collect();
        assert_eq!(lens, [1, 3, 1]);
        assert_eq!(
            face.column(1)[1],
            FaceItem::Brick {
                bz: 2,
                parts: vec![(0, !(1u64 << (4 * 8 + 1)))]
            }
        );
        assert_eq!(comps.x_face(1).items.len(), 3);
    }
}
