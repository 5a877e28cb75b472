//! Which non-surface voxels are inside: the two flood fills (`Fill::Scene`, `Fill::Objects`).
//!
//! - [`Solid::Scene`]: the paper's flood fill from the outside of the whole scene; whatever it
//!   does not reach is inside. A car body's cabin is then inside, as the body encloses it.
//! - [`Solid::Objects`]: a voxel is inside when its centre is inside at least one closed object,
//!   by the parity of the object's surfaces crossed on the way out (computed from the triangles
//!   by `generate`). The cabin of a car body modelled as an outer and an inner skin is crossed
//!   twice, so it stays outside and a part can move inside it, however thin the wall; an open
//!   object encloses nothing and adds only its surface.
//!
//! This module only holds the result, as bricks: masks for bricks partly inside and key
//! ranges for bricks wholly inside, so it follows the surface, not the volume.

use rustc_hash::FxHashMap;

use super::fill::Outside;
use super::mask::Mask512;
use super::KeyRange;

/// The inside of a scene, from one of the two fills.
#[derive(Clone, Debug)]
pub enum Solid {
    /// Flood fill from the outside of the whole scene: the [`Outside`] of the whole grid
    /// (`base` 0), or of one slab of it, out of core, a sub-grid whose brick keys are the
    /// scene's minus `base`.
    Scene {
        /// The outside, in its grid's own keys.
        outside: Outside,
        /// Scene key of that grid's key 0.
        base: u64,
    },
    /// The union of what each object encloses.
    Objects(ObjectsInside),
}

impl Solid {
    /// The outside voxels of the scene's surface brick `key`, whose surface voxels are
    /// `surface`.
    pub fn outside_voxels(&self, key: u64, surface: &Mask512) -> Mask512 {
        match self {
            Solid::Scene { outside, base } => outside.outside_voxels_of(key - base).unwrap_or(Mask512::EMPTY),
            Solid::Objects(o) => Mask512::FULL.and_not(&o.inside_of(key).or(surface)),
        }
    }

    /// The outside voxels of brick `key`, which holds no surface voxel of the scene, when it is
    /// partly inside (the winding fill's inside can end in the air); `None` when it is all on
    /// one side, which [`Solid::empty_brick_is_outside`] tells.
    pub fn outside_voxels_of_empty(&self, key: u64) -> Option<Mask512> {
        match self {
            Solid::Scene { .. } => None,
            Solid::Objects(o) => {
                let inside = o.inside_of(key);
                (inside != Mask512::EMPTY && inside != Mask512::FULL).then(|| Mask512::FULL.and_not(&inside))
            }
        }
    }

    /// Whether brick `key`, which holds no surface voxel of the scene, is outside.
    pub fn empty_brick_is_outside(&self, key: u64) -> bool {
        match self {
            Solid::Scene { outside, base } => outside.empty_brick_is_outside(key - base),
            Solid::Objects(o) => !o.is_fully_inside(key),
        }
    }

    /// Ranges of brick keys `[start, end)`, in key order and disjoint, whose bricks are wholly
    /// inside except for any surface they hold (the caller removes stored bricks).
    pub fn enclosed_spans(&self) -> Vec<(u64, u64)> {
        match self {
            Solid::Scene { outside, base } => outside.enclosed_spans().map(|(s, e)| (s + base, e + base)).collect(),
            Solid::Objects(o) => o.full.iter().map(|r| (r.start, r.end)).collect(),
        }
    }
}

/// The union of the insides of several objects, in the scene grid's brick keys.
#[derive(Clone, Debug, Default)]
pub struct ObjectsInside {
    /// Bricks partly inside some object (surface bricks of that object): the inside voxels.
    partial: FxHashMap<u64, Mask512>,
    /// Key ranges of bricks wholly inside some object, sorted, disjoint and merged.
    full: Vec<KeyRange>,
}

impl ObjectsInside {
    /// The inside voxels of brick `key`, surface excluded.
    pub fn inside_of(&self, key: u64) -> Mask512 {
        if self.is_fully_inside(key) {
            return Mask512::FULL;
        }
        self.partial.get(&key).copied().unwrap_or(Mask512::EMPTY)
    }

    fn is_fully_inside(&self, key: u64) -> bool {
        let i = self.full.partition_point(|r| r.end <= key);
        self.full.get(i).is_some_and(|r| r.start <= key)
    }

    /// Add the inside voxels of one brick column: `columns[c]` lists, for voxel column
    /// `c = x + 8·y` of brick column `(bx, by)`, its inside voxel ranges `[z0, z1)`, sorted
    /// and disjoint. `nb` is the grid's size in bricks.
    pub fn add_brick_column(&mut self, nb: [u32; 3], bx: u32, by: u32, columns: &[Vec<(u32, u32)>; 64]) {
        let key = |bz: u32| (bx as u64 * nb[1] as u64 + by as u64) * nb[2] as u64 + bz as u64;
        // Voxel ranges inside in all 64 columns: bricks wholly within them are wholly inside.
        let mut common: Vec<(u32, u32)> = columns[0].clone();
        for c in &columns[1..] {
            common = intersect(&common, c);
            if common.is_empty() {
                break;
            }
        }
        let mut full_bricks: Vec<(u32, u32)> = Vec::new();
        for &(z0, z1) in &common {
            let (b0, b1) = (z0.div_ceil(8), z1 / 8);
            if b0 < b1 {
                full_bricks.push((b0, b1));
                self.full.push(KeyRange {
                    start: key(b0),
                    end: key(b1),
                });
            }
        }
        let is_full = |bz: u32| full_bricks.iter().any(|&(b0, b1)| b0 <= bz && bz < b1);
        for (c, ranges) in columns.iter().enumerate() {
            let (x, y) = (c as u32 % 8, c as u32 / 8);
            for &(z0, z1) in ranges {
                let mut z = z0;
                while z < z1 {
                    let bz = z / 8;
                    let end = z1.min((bz + 1) * 8);
                    if !is_full(bz) {
                        let m = self.partial.entry(key(bz)).or_insert(Mask512::EMPTY);
                        for zz in z..end {
                            m.set(crate::grid::local_index(x, y, zz % 8));
                        }
                    }
                    z = end;
                }
            }
        }
    }

    /// Add what another set of objects encloses.
    pub fn merge(&mut self, other: ObjectsInside) {
        for (key, m) in other.partial {
            let e = self.partial.entry(key).or_insert(Mask512::EMPTY);
            *e = e.or(&m);
        }
        self.full.extend(other.full);
    }

    /// Sort and merge the ranges; call once after the last object.
    pub fn finish(mut self) -> ObjectsInside {
        self.full.sort_unstable_by_key(|r| r.start);
        let mut merged: Vec<KeyRange> = Vec::with_capacity(self.full.len());
        for r in self.full {
            match merged.last_mut() {
                Some(last) if r.start <= last.end => last.end = last.end.max(r.end),
                _ => merged.push(r),
            }
        }
        self.full = merged;
        // A brick wholly inside one object needs no partial mask from another.
        let full = std::mem::take(&mut self.full);
        let probe = ObjectsInside {
            partial: FxHashMap::default(),
            full,
        };
        self.partial.retain(|k, _| !probe.is_fully_inside(*k));
        self.full = probe.full;
        self
    }
}

/// The intersection of two sorted, disjoint lists of ranges.
fn intersect(a: &[(u32, u32)], b: &[(u32, u32)]) -> Vec<(u32, u32)> {
    let (mut i, mut j, mut out) = (0, 0, Vec::new());
    while i < a.len() && j < b.len() {
        let (lo, hi) = (a[i].0.max(b[j].0), a[i].1.min(b[j].1));
        if lo < hi {
            out.push((lo, hi));
        }
        if a[i].1 < b[j].1 {
            i += 1;
        } else {
            j += 1;
        }
    }
    out
}
