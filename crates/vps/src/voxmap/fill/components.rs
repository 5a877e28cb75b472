//! Connected components of a slab's open voxels, for grids too large to fill at once: labels
//! per slab, united across slab faces, then turned into each slab's outside.

use super::*;

/// Label of no component: an empty gap.
pub(super) const NO_LABEL: u32 = u32::MAX;

/// The connected components (6-connected) of the non-surface voxels of a grid of bricks, whose
/// boundary is a wall. Held like [`Outside`]: one label per span, and per surface brick its
/// open voxels split into parts that are connected inside the brick, each with a label.
#[derive(Clone, Debug)]
pub struct Components {
    pub(super) cols: Columns,
    pub(super) count: u32,
    /// Label of each gap, by gap id; [`NO_LABEL`] for an empty gap.
    pub(super) span_label: Vec<u32>,
    /// The parts of surface brick `i` are `part_start[i]..part_start[i + 1]`.
    pub(super) part_start: Vec<u32>,
    /// Voxels of each part.
    pub(super) parts: Vec<Mask512>,
    /// Label of each part.
    pub(super) part_label: Vec<u32>,
}

/// The labels on one x face of a grid, column by column (brick y), each column as its spans and
/// surface bricks in z order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct XFace {
    pub(super) nz: u32,
    /// Items of brick column `by` are `col_start[by]..col_start[by + 1]`.
    pub(super) col_start: Vec<u32>,
    pub(super) items: Vec<FaceItem>,
}

/// One node of a grid's x face.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FaceItem {
    /// Empty bricks `z0..z1` (brick z), all of one label.
    Span {
        /// First brick z.
        z0: u32,
        /// One past the last brick z.
        z1: u32,
        /// Their label.
        label: u32,
    },
    /// A surface brick at brick z `bz`.
    Brick {
        /// Brick z.
        bz: u32,
        /// Each label with open voxels on the face, and those voxels: bit `z * 8 + y` (local
        /// coordinates). Labels are distinct and bits never empty.
        parts: Vec<(u32, u64)>,
    },
}

impl FaceItem {
    /// Brick z range `[z0, z1)` of the item.
    pub fn z_range(&self) -> (u32, u32) {
        match *self {
            FaceItem::Span { z0, z1, .. } => (z0, z1),
            FaceItem::Brick { bz, .. } => (bz, bz + 1),
        }
    }
}

impl XFace {
    /// Bricks along y.
    pub fn ny(&self) -> u32 {
        (self.col_start.len() - 1) as u32
    }

    /// Bricks along z.
    pub fn nz(&self) -> u32 {
        self.nz
    }

    /// The items of brick column `by`, in z order; empty gaps have none.
    pub fn column(&self, by: u32) -> &[FaceItem] {
        let by = by as usize;
        &self.items[self.col_start[by] as usize..self.col_start[by + 1] as usize]
    }
}

/// Union-find with path halving and union by rank.
pub(crate) struct UnionFind {
    parent: Vec<u32>,
    rank: Vec<u8>,
}

impl UnionFind {
    pub(crate) fn new(n: usize) -> UnionFind {
        UnionFind {
            parent: (0..n as u32).collect(),
            rank: vec![0; n],
        }
    }

    pub(crate) fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let p = self.parent[x as usize];
            self.parent[x as usize] = self.parent[p as usize];
            x = p;
        }
        x
    }

    pub(crate) fn union(&mut self, a: u32, b: u32) {
        let (a, b) = (self.find(a), self.find(b));
        if a == b {
            return;
        }
        let (ra, rb) = (self.rank[a as usize], self.rank[b as usize]);
        if ra < rb {
            self.parent[a as usize] = b;
        } else {
            self.parent[b as usize] = a;
            if ra == rb {
                self.rank[a as usize] += 1;
            }
        }
    }
}

/// Split the open voxels of a brick with surface voxels `wall` into parts connected inside it.
pub(super) fn split_parts(wall: &Mask512, parts: &mut Vec<Mask512>) {
    let open = Mask512::FULL.and_not(wall);
    let mut rest = open;
    loop {
        let Some(v) = rest.iter().next() else {
            return;
        };
        let mut seed = Mask512::EMPTY;
        seed.set(v);
        let part = seed.flood_within(&open);
        rest = rest.and_not(&part);
        parts.push(part);
    }
}

/// The voxels of `m` at local x = `lx`, as bit `z * 8 + y`.
pub(super) fn x_face_bits(m: &Mask512, lx: u32) -> u64 {
    let mut bits = 0u64;
    for (z, &w) in m.0.iter().enumerate() {
        // Bits y * 8 (one per row) folded down into the low byte.
        let mut r = (w >> lx) & 0x0101_0101_0101_0101;
        r |= r >> 7;
        r |= r >> 14;
        r |= r >> 28;
        bits |= (r & 0xff) << (8 * z);
    }
    bits
}

impl Components {
    /// Label the components of the non-surface voxels of a grid of `nb` bricks with surface
    /// masks `surface` (sorted by key, as for [`Outside::flood`]). Labels are `0..count()`,
    /// numbered by first appearance over gaps in id order, then parts of surface bricks in order.
    pub fn label(nb: [u32; 3], surface: &[(u64, Mask512)]) -> Components {
        let cols = Columns::new(nb, surface);
        let ngaps = cols.gap_count();
        let mut part_start = Vec::with_capacity(surface.len() + 1);
        let mut parts = Vec::with_capacity(surface.len());
        part_start.push(0u32);
        for (_, wall) in surface {
            split_parts(wall, &mut parts);
            part_start.push(parts.len() as u32);
        }
        let parts_of = |i: u32| part_start[i as usize] as usize..part_start[i as usize + 1] as usize;
        // Union-find nodes: gap ids, then `ngaps + p` for part p.
        let part_node = |p: usize| (ngaps + p) as u32;
        let mut uf = UnionFind::new(ngaps + parts.len());
        let join_face = |uf: &mut UnionFind, node: u32, brick: u32, face: Face| {
            let f = Mask512::face(face);
            for p in parts_of(brick) {
                if !parts[p].and(&f).is_empty() {
                    uf.union(node, part_node(p));
                }
            }
        };
        for g in cols.gaps() {
            if let Some(b) = g.below {
                join_face(&mut uf, g.id, b, Face { axis: 2, side: 1 });
            }
            if let Some(a) = g.above {
                join_face(&mut uf, g.id, a, Face { axis: 2, side: 0 });
            }
            for face in SIDES {
                let Some(nc) = cols.side_column(g.col, face) else {
                    continue;
                };
                cols.items_in(nc, g.z0, g.z1, |node, _, _| match node {
                    Node::Span(s) => uf.union(g.id, s),
                    Node::Brick(k) => join_face(&mut uf, g.id, k, face.opposite()),
                });
            }
        }
        // Brick to brick, each touching pair once from its low side.
        for c in 0..cols.ncols() {
            let (s, e) = cols.bricks_of(c);
            for i in s..e {
                for face in [
                    Face { axis: 0, side: 1 },
                    Face { axis: 1, side: 1 },
                    Face { axis: 2, side: 1 },
                ] {
                    let Some(Node::Brick(j)) = cols.neighbour(c, i, face) else {
                        continue;
                    };
                    for p in parts_of(i as u32) {
                        let across = parts[p].across(face);
                        if across.is_empty() {
                            continue;
                        }
                        for q in parts_of(j) {
                            if !parts[q].and(&across).is_empty() {
                                uf.union(part_node(p), part_node(q));
                            }
                        }
                    }
                }
            }
        }
        // Number the roots in a fixed order, so equal input gives equal labels.
        let mut root_label = vec![NO_LABEL; ngaps + parts.len()];
        let mut count = 0u32;
        let mut label_node = |uf: &mut UnionFind, node: u32| {
            let r = uf.find(node) as usize;
            if root_label[r] == NO_LABEL {
                root_label[r] = count;
                count += 1;
            }
            root_label[r]
        };
        let mut span_label = vec![NO_LABEL; ngaps];
        for g in cols.gaps() {
            span_label[g.id as usize] = label_node(&mut uf, g.id);
        }
        let part_label: Vec<u32> = (0..parts.len()).map(|p| label_node(&mut uf, part_node(p))).collect();
        Components {
            cols,
            count,
            span_label,
            part_start,
            parts,
            part_label,
        }
    }

    /// Number of components.
    pub fn count(&self) -> u32 {
        self.count
    }

    pub(super) fn parts_of(&self, i: u32) -> std::ops::Range<usize> {
        self.part_start[i as usize] as usize..self.part_start[i as usize + 1] as usize
    }

    /// The label of voxel `v`; `None` for a surface voxel or one beyond the grid.
    pub fn label_of(&self, v: [u32; 3]) -> Option<u32> {
        let (b, local) = split_voxel(v);
        let nb = self.cols.nb;
        if (0..3).any(|a| b[a] >= nb[a]) {
            return None;
        }
        let c = b[0] as usize * nb[1] as usize + b[1] as usize;
        match self.cols.node_at(c, b[2]) {
            Node::Span(id) => Some(self.span_label[id as usize]),
            Node::Brick(i) => self
                .parts_of(i)
                .find(|&p| self.parts[p].get(local))
                .map(|p| self.part_label[p]),
        }
    }

    /// The labels on the low (`side` 0, voxel x = 0) or high (`side` 1, the last voxel x) x
    /// face of the grid: what [`Components::unite_across`] needs from this slab.
    pub fn x_face(&self, side: usize) -> XFace {
        let [nx, ny, nz] = self.cols.nb;
        let (bx, lx) = if side == 0 { (0, 0) } else { (nx - 1, 7) };
        let mut col_start = Vec::with_capacity(ny as usize + 1);
        let mut items = Vec::new();
        col_start.push(0u32);
        for by in 0..ny {
            let c = bx as usize * ny as usize + by as usize;
            self.cols.items_in(c, 0, nz, |node, z0, z1| match node {
                Node::Span(id) => items.push(FaceItem::Span {
                    z0,
                    z1,
                    label: self.span_label[id as usize],
                }),
                Node::Brick(i) => {
                    let mut parts: Vec<(u32, u64)> = Vec::new();
                    for p in self.parts_of(i) {
                        let bits = x_face_bits(&self.parts[p], lx);
                        if bits == 0 {
                            continue;
                        }
                        let label = self.part_label[p];
                        match parts.iter_mut().find(|e| e.0 == label) {
                            Some(e) => e.1 |= bits,
                            None => parts.push((label, bits)),
                        }
                    }
                    if !parts.is_empty() {
                        items.push(FaceItem::Brick { bz: z0, parts });
                    }
                }
            });
            col_start.push(items.len() as u32);
        }
        XFace { nz, col_start, items }
    }

    /// Call `unite(a, b)` for labels `a` of `high` (a slab's high x face) and `b` of `low` (the
    /// next slab's low x face) that meet across the boundary; at most once per pair of
    /// overlapping items, or of parts in two overlapping bricks.
    pub fn unite_across(high: &XFace, low: &XFace, mut unite: impl FnMut(u32, u32)) {
        assert!(high.ny() == low.ny() && high.nz == low.nz, "faces of different sizes");
        for by in 0..high.ny() {
            let (a, b) = (high.column(by), low.column(by));
            let (mut i, mut j) = (0, 0);
            while i < a.len() && j < b.len() {
                let (a0, a1) = a[i].z_range();
                let (b0, b1) = b[j].z_range();
                if a0 < b1 && b0 < a1 {
                    unite_items(&a[i], &b[j], &mut unite);
                }
                if a1 <= b1 {
                    i += 1;
                } else {
                    j += 1;
                }
            }
        }
    }

    /// The [`Outside`] whose reached voxels are exactly those with a label for which
    /// `is_outside` holds.
    pub fn into_outside(self, mut is_outside: impl FnMut(u32) -> bool) -> Outside {
        let reached = (0..self.part_start.len() - 1)
            .map(|i| {
                self.parts_of(i as u32)
                    .filter(|&p| is_outside(self.part_label[p]))
                    .fold(Mask512::EMPTY, |m, p| m.or(&self.parts[p]))
            })
            .collect();
        let span_reached = self
            .span_label
            .iter()
            .map(|&l| l != NO_LABEL && is_outside(l))
            .collect();
        Outside {
            cols: self.cols,
            reached,
            span_reached,
        }
    }
}

/// Unite the labels of two overlapping face items that touch: a span's voxels are all open, so
/// it meets every part of a brick; two bricks meet where their face bits do.
pub(super) fn unite_items(a: &FaceItem, b: &FaceItem, unite: &mut impl FnMut(u32, u32)) {
    match (a, b) {
        (FaceItem::Span { label: la, .. }, FaceItem::Span { label: lb, .. }) => unite(*la, *lb),
        (FaceItem::Span { label: la, .. }, FaceItem::Brick { parts, .. }) => {
            for &(lb, _) in parts {
                unite(*la, lb);
            }
        }
        (FaceItem::Brick { parts, .. }, FaceItem::Span { label: lb, .. }) => {
            for &(la, _) in parts {
                unite(la, *lb);
            }
        }
        (FaceItem::Brick { parts: pa, .. }, FaceItem::Brick { parts: pb, .. }) => {
            for &(la, ba) in pa {
                for &(lb, bb) in pb {
                    if ba & bb != 0 {
                        unite(la, lb);
                    }
                }
            }
        }
    }
}
