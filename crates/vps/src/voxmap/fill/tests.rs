//! The flood fill and the slab components against a dense breadth-first search on random grids.

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
