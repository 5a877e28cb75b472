//! The sparse voxmap: bricks of 8³ signed layer values, and uniform tiles for everything else.
//!
//! This module knows nothing of meshes or files. A voxmap holds
//! - stored bricks, each 512 `i8` values, sorted by brick key;
//! - inside tiles: runs of brick keys whose voxels are all deep inside, `+(layers + 1)`;
//! - everything else is far outside, `-(layers + 1)`.

pub mod fill;
pub mod layers;
pub mod mask;
pub mod solid;

use crate::grid::{split_voxel, Grid, BRICK_VOXELS};
pub use mask::Mask512;

/// The 512 values of one brick, local index x fastest (see [`crate::grid::local_index`]).
pub type BrickValues = [i8; BRICK_VOXELS];

/// Largest number of layers: values stay within `i8` with room for the deep value.
pub const MAX_LAYERS: u8 = 126;

/// The signed distances of one brick's voxel centres to the surface, in steps of
/// [`DISTANCE_STEP`] voxels, positive inside, local index order like [`BrickValues`].
pub type BrickDistances = [i16; BRICK_VOXELS];

/// The step of the stored distances, in voxels: 1/32, so a distance is within 1/64 of a voxel
/// of the exact one, and `i16` holds ±1024 voxels, more than [`distance_reach`] of
/// [`MAX_LAYERS`]. Finer steps cost file size for nothing a hand can feel: on Nefertiti's
/// `.vxm` (5 layers) 1/256 took 21.1 MB against 15.8 MB for 1/32 (8.3 MB without distances),
/// as zstd cannot pack the rounding noise of the finer step.
pub const DISTANCE_STEP: f64 = 1.0 / STEPS_PER_VOXEL as f64;

/// Steps of [`DISTANCE_STEP`] in a voxel.
pub const STEPS_PER_VOXEL: i16 = 32;

/// How far the stored distances reach, in voxels, for `layers` layers: half a voxel beyond the
/// centres of the last layer. Distances are clamped to ±this: a voxel beyond the layers, or in
/// a tile, is at least this far from the surface (its chessboard distance to the nearest
/// surface voxel is more than `layers`, so on one axis it is at least `layers + 0.5` from any
/// point of that voxel).
pub fn distance_reach(layers: u8) -> f64 {
    layers as f64 + 0.5
}

/// The stored distance of a tile, or of a stored voxel beyond the layers, of value `value`:
/// the reach, with the value's sign.
pub fn far_distance(layers: u8, value: i8) -> i16 {
    let r = (distance_reach(layers) / DISTANCE_STEP) as i16;
    if value > 0 {
        r
    } else {
        -r
    }
}

/// Whether a contact can read the distance of a voxel of value `value`: it lies within the
/// first outer layer (`value ≥ −1`).
///
/// Why the others are never read by the default, trilinear blend (the sharp blend of
/// [`crate::Penetration::Sharp`] reads the bounds they hold in its outer ring, the same from a
/// file as in memory): the distance of a point is the blend of the eight voxel
/// centres around it, which are 26-neighbours of each other, and no voxel `≤ −2` has a
/// neighbour `≥ 0` (`docs/VOXMAP.md`, "Layers"). If one of the eight is at `≤ −2`, all are at
/// `≤ −1`, outside, with negative distances, and so is the blend: the point is not in contact,
/// whatever those distances are. Voxmaps keep [`outer_distance`] for them instead, which files
/// need not store.
#[inline]
pub fn distance_is_read(value: i8) -> bool {
    value >= -1
}

/// The distance, in steps of [`DISTANCE_STEP`], that a voxel of value `value ≤ −2` holds in
/// place of its own (see [`distance_is_read`]): the nearest to the surface its layer allows,
/// `−(|value| − ½)` voxels. Its chessboard distance to the nearest surface voxel is `|value|`, so
/// on one axis its centre is at least that less half a voxel from any point of the mesh. For
/// the far-outside value `−(layers + 1)` this is [`far_distance`], minus the reach.
#[inline]
pub fn outer_distance(value: i8) -> i16 {
    i16::from(value) * STEPS_PER_VOXEL + STEPS_PER_VOXEL / 2
}

/// Whether `distance` (in steps) lies on the side of the surface that `value` says, for a
/// voxel whose distance a contact reads: positive inside (`value ≥ 1`), negative outside
/// (`value = −1`), either on the surface (0). A voxel no triangle touches has its centre more
/// than half a voxel from the mesh, so its distance is never 0; and a contact's proof that a
/// voxel of −1 adds nothing ([`distance_is_read`]) needs it negative.
#[inline]
pub fn distance_on_its_side(value: i8, distance: i16) -> bool {
    !distance_is_read(value) || value == 0 || (value > 0 && distance > 0) || (value < 0 && distance < 0)
}

/// Replace the distances of the voxels of `values` that no contact reads by their
/// [`outer_distance`].
pub fn bound_outer_distances(values: &BrickValues, distances: &mut BrickDistances) {
    for (&v, d) in values.iter().zip(distances.iter_mut()) {
        if !distance_is_read(v) {
            *d = outer_distance(v);
        }
    }
}

/// A half-open range `[start, end)` of brick keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct KeyRange {
    /// First key in the range.
    pub start: u64,
    /// One past the last key.
    pub end: u64,
}

/// One brick whose values are not all the same far value.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Brick {
    /// Brick key, see [`Grid::brick_key`].
    pub key: u64,
    /// Its values.
    pub values: Box<BrickValues>,
}

/// A stored brick's values and, if the voxmap carries them, its signed distances: what a
/// file's brick decodes to, and what the haptic query's cache holds.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StoredBrick {
    /// The values.
    pub values: BrickValues,
    /// The signed distances, in steps of [`DISTANCE_STEP`] voxels.
    pub distances: Option<BrickDistances>,
}

impl StoredBrick {
    /// Zeros and no distances: a brick to decode into.
    pub const EMPTY: StoredBrick = StoredBrick {
        values: [0; BRICK_VOXELS],
        distances: None,
    };
}

/// What one brick position holds: a stored brick, through whatever owns or borrows its values
/// (`&BrickValues` in memory, a `Box` read from a file, an `Arc` in a cache), or a uniform tile.
/// One enum for all three, so a look-up is written once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BrickSlot<P> {
    /// A stored brick.
    Stored(P),
    /// A uniform tile: every voxel has this value.
    Tile(i8),
}

/// A brick borrowed from a [`Voxmap`] in memory.
pub type BrickRef<'a> = BrickSlot<&'a BrickValues>;

impl<P: std::ops::Deref<Target = BrickValues>> BrickSlot<P> {
    /// The value of the voxel at local index `local` (see [`crate::grid::local_index`]).
    #[inline]
    pub fn value(&self, local: usize) -> i8 {
        match self {
            BrickSlot::Stored(values) => values[local],
            BrickSlot::Tile(t) => *t,
        }
    }
}

impl<P> BrickSlot<P> {
    /// The same brick with its values owned another way (boxed, shared).
    pub fn map<Q>(self, f: impl FnOnce(P) -> Q) -> BrickSlot<Q> {
        match self {
            BrickSlot::Stored(values) => BrickSlot::Stored(f(values)),
            BrickSlot::Tile(t) => BrickSlot::Tile(t),
        }
    }
}

/// Voxel counts of a voxmap.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VoxmapCounts {
    /// Voxels with value 0.
    pub surface_voxels: u64,
    /// Voxels with value > 0, counting those in inside tiles.
    pub inner_voxels: u64,
    /// Bricks stored with their values.
    pub bricks_stored: u64,
    /// Bricks that are uniform inside tiles.
    pub inside_tile_bricks: u64,
}

/// A voxmap held in memory.
#[derive(Clone, Debug, PartialEq)]
pub struct Voxmap {
    grid: Grid,
    layers: u8,
    bricks: Vec<Brick>,
    inside: Vec<KeyRange>,
    counts: VoxmapCounts,
    /// The signed distances of the stored bricks' voxels, brick by brick like `bricks`, if
    /// computed (see [`Voxmap::with_distances`]).
    distances: Option<Vec<BrickDistances>>,
}

/// The value of voxels deep inside: `+(layers + 1)`.
#[inline]
pub fn inside_value(layers: u8) -> i8 {
    layers as i8 + 1
}

/// The value of voxels far outside, and of every point beyond the grid: `-(layers + 1)`.
#[inline]
pub fn outside_value(layers: u8) -> i8 {
    -(layers as i8) - 1
}

impl Voxmap {
    /// Assemble a voxmap from bricks sorted by key and disjoint sorted inside runs.
    ///
    /// Panics in debug builds if the order is wrong; generation builds these in order.
    pub fn from_parts(grid: Grid, layers: u8, bricks: Vec<Brick>, inside: Vec<KeyRange>) -> Voxmap {
        debug_assert!(bricks.windows(2).all(|w| w[0].key < w[1].key));
        debug_assert!(inside.windows(2).all(|w| w[0].end <= w[1].start));
        let mut counts = VoxmapCounts {
            bricks_stored: bricks.len() as u64,
            ..Default::default()
        };
        for b in &bricks {
            for &v in b.values.iter() {
                counts.surface_voxels += (v == 0) as u64;
                counts.inner_voxels += (v > 0) as u64;
            }
        }
        counts.inside_tile_bricks = inside.iter().map(|r| r.end - r.start).sum();
        counts.inner_voxels += counts.inside_tile_bricks * BRICK_VOXELS as u64;
        Voxmap {
            grid,
            layers,
            bricks,
            inside,
            counts,
            distances: None,
        }
    }

    /// The same voxmap carrying the signed distances of its stored bricks' voxels, one array
    /// per brick in the order of [`Voxmap::bricks`]: the sub-voxel field that the haptic query
    /// interpolates (`docs/VOXMAP.md`). Tiles need none: theirs is [`far_distance`]. Voxels
    /// beyond the first outer layer keep their [`outer_distance`] instead of the one given,
    /// which no contact reads ([`distance_is_read`]), so that a voxmap is the same after a
    /// round trip through a file, which does not store them.
    ///
    /// # Panics
    /// If there is not one array per stored brick.
    pub fn with_distances(self, mut distances: Vec<BrickDistances>) -> Voxmap {
        for (brick, d) in self.bricks.iter().zip(&mut distances) {
            bound_outer_distances(&brick.values, d);
        }
        self.with_distances_as_given(distances)
    }

    /// [`Voxmap::with_distances`] without the outer distances replaced: tests prove with it
    /// that no contact reads them.
    pub(crate) fn with_distances_as_given(mut self, distances: Vec<BrickDistances>) -> Voxmap {
        assert_eq!(
            distances.len(),
            self.bricks.len(),
            "one distance array per stored brick"
        );
        self.distances = Some(distances);
        self
    }

    /// The stored bricks, taken back (the out-of-core path lends a slab's bricks to a voxmap
    /// for its distances).
    pub(crate) fn into_bricks(self) -> Vec<Brick> {
        self.bricks
    }

    /// The signed distances of the stored bricks, if the voxmap carries them.
    pub fn distances(&self) -> Option<&[BrickDistances]> {
        self.distances.as_deref()
    }

    /// The signed distances of brick `key`: `Stored` for a stored brick, `Tile` with the
    /// value of a tile (whose distance is [`far_distance`]); `None` without distances.
    pub fn brick_distances(&self, key: u64) -> Option<BrickSlot<&BrickDistances>> {
        let distances = self.distances.as_ref()?;
        Some(match self.bricks.binary_search_by_key(&key, |b| b.key) {
            Ok(i) => BrickSlot::Stored(&distances[i]),
            Err(_) => BrickSlot::Tile(self.tile_value(key)),
        })
    }

    /// What brick `key` holds, with its distances if the voxmap carries them: as
    /// [`crate::storage::VoxmapFile::stored_brick`], from one search.
    pub fn stored_brick(&self, key: u64) -> BrickSlot<StoredBrick> {
        match self.bricks.binary_search_by_key(&key, |b| b.key) {
            Ok(i) => BrickSlot::Stored(StoredBrick {
                values: *self.bricks[i].values,
                distances: self.distances.as_ref().map(|d| d[i]),
            }),
            Err(_) => BrickSlot::Tile(self.tile_value(key)),
        }
    }

    /// The value of brick `key`, which is not stored: inside or far outside.
    fn tile_value(&self, key: u64) -> i8 {
        if in_runs(&self.inside, key) {
            inside_value(self.layers)
        } else {
            outside_value(self.layers)
        }
    }

    /// The voxmap of a signed distance field (world units, negative inside; its layers are then
    /// one per unit): each voxel holds `-distance(centre)` rounded and clamped to the layers, so the surface is 0, inside positive. Bricks all far outside are dropped and
    /// bricks all deep inside become inside runs, as generation stores them.
    ///
    /// Evaluates every voxel of the grid: for tests, benches and small synthetic voxmaps.
    pub fn from_signed_distance(grid: Grid, layers: u8, distance: impl Fn(glam::DVec3) -> f64) -> Voxmap {
        let (deep, far) = (inside_value(layers), outside_value(layers));
        let n = grid.brick_dims();
        let (mut bricks, mut inside) = (Vec::new(), Vec::<KeyRange>::new());
        for b in (0..n[0]).flat_map(|x| (0..n[1]).flat_map(move |y| (0..n[2]).map(move |z| [x, y, z]))) {
            let key = grid.brick_key(b);
            let values: Box<BrickValues> = Box::new(std::array::from_fn(|i| {
                let l = [i as u32 & 7, (i as u32 >> 3) & 7, i as u32 >> 6];
                let c = grid.voxel_center([b[0] * 8 + l[0], b[1] * 8 + l[1], b[2] * 8 + l[2]]);
                (-distance(c)).round().clamp(far as f64, deep as f64) as i8
            }));
            if values.iter().all(|&v| v == far) {
                continue;
            }
            if values.iter().all(|&v| v == deep) {
                match inside.last_mut() {
                    Some(r) if r.end == key => r.end += 1,
                    _ => inside.push(KeyRange {
                        start: key,
                        end: key + 1,
                    }),
                }
                continue;
            }
            bricks.push(Brick { key, values });
        }
        Voxmap::from_parts(grid, layers, bricks, inside)
    }

    /// The grid.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Number of layers on each side of the surface.
    pub fn layers(&self) -> u8 {
        self.layers
    }

    /// Stored bricks, sorted by key.
    pub fn bricks(&self) -> &[Brick] {
        &self.bricks
    }

    /// Inside tile runs, sorted and disjoint.
    pub fn inside_runs(&self) -> &[KeyRange] {
        &self.inside
    }

    /// Voxel counts.
    pub fn counts(&self) -> VoxmapCounts {
        self.counts
    }

    /// What brick `key` holds.
    pub fn brick(&self, key: u64) -> BrickRef<'_> {
        if let Ok(i) = self.bricks.binary_search_by_key(&key, |b| b.key) {
            return BrickRef::Stored(&self.bricks[i].values);
        }
        BrickRef::Tile(self.tile_value(key))
    }

    /// The value of voxel `v`; beyond the grid, the far outside value.
    pub fn value(&self, v: [u32; 3]) -> i8 {
        if (0..3).any(|a| v[a] >= self.grid.dims[a]) {
            return outside_value(self.layers);
        }
        let (b, local) = split_voxel(v);
        self.brick(self.grid.brick_key(b)).value(local)
    }

    /// The value of the voxel containing world point `p`; beyond the grid, the far outside value.
    pub fn value_at(&self, p: glam::DVec3) -> i8 {
        match self.grid.voxel_of(p) {
            Some(v) => self.value(v),
            None => outside_value(self.layers),
        }
    }
}

/// Whether `key` lies in one of the sorted, disjoint `runs`.
pub fn in_runs(runs: &[KeyRange], key: u64) -> bool {
    let i = runs.partition_point(|r| r.end <= key);
    i < runs.len() && runs[i].start <= key
}
