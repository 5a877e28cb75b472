//! One bit per voxel of a brick, with the shifts that flood fill and layering need.
//!
//! Word `z` holds the slice at local z; bit `y * 8 + x` of it is voxel (x, y, z), the same order
//! as [`crate::grid::local_index`]. Dilation by one voxel along an axis is a handful of shifts, so
//! the fill and the layers move 64 voxels per instruction.

/// Bits of a word whose local x is 0.
const X0: u64 = 0x0101_0101_0101_0101;
/// Bits of a word whose local x is 7.
const X7: u64 = 0x8080_8080_8080_8080;
/// Bits of a word whose local y is 0.
const Y0: u64 = 0x0000_0000_0000_00ff;
/// Bits of a word whose local y is 7.
const Y7: u64 = 0xff00_0000_0000_0000;

/// A set of voxels of one brick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Mask512(pub [u64; 8]);

/// One of the six faces of a brick, as (axis, side): side 0 is the low face, 1 the high face.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Face {
    /// 0 = x, 1 = y, 2 = z.
    pub axis: usize,
    /// 0 = low side (local coordinate 0), 1 = high side (local coordinate 7).
    pub side: usize,
}

impl Face {
    /// All six faces.
    pub const ALL: [Face; 6] = [
        Face { axis: 0, side: 0 },
        Face { axis: 0, side: 1 },
        Face { axis: 1, side: 0 },
        Face { axis: 1, side: 1 },
        Face { axis: 2, side: 0 },
        Face { axis: 2, side: 1 },
    ];

    /// The face of the neighbouring brick that touches this one.
    pub fn opposite(self) -> Face {
        Face {
            axis: self.axis,
            side: 1 - self.side,
        }
    }
}

/// Masks keyed by brick, sorted by key, with the masks of equal keys joined.
pub fn union_by_key(mut masks: Vec<(u64, Mask512)>) -> Vec<(u64, Mask512)> {
    masks.sort_unstable_by_key(|m| m.0);
    let mut out: Vec<(u64, Mask512)> = Vec::with_capacity(masks.len());
    for (key, m) in masks {
        match out.last_mut() {
            Some(last) if last.0 == key => last.1 = last.1.or(&m),
            _ => out.push((key, m)),
        }
    }
    out
}

impl Mask512 {
    /// No voxel.
    pub const EMPTY: Mask512 = Mask512([0; 8]);
    /// Every voxel.
    pub const FULL: Mask512 = Mask512([u64::MAX; 8]);

    /// Whether no bit is set.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.0.iter().all(|&w| w == 0)
    }

    /// Whether every bit is set.
    #[inline]
    pub fn is_full(&self) -> bool {
        self.0.iter().all(|&w| w == u64::MAX)
    }

    /// Number of set bits.
    #[inline]
    pub fn count(&self) -> u32 {
        self.0.iter().map(|w| w.count_ones()).sum()
    }

    /// Whether local voxel `i` (see [`crate::grid::local_index`]) is set.
    #[inline]
    pub fn get(&self, i: usize) -> bool {
        self.0[i >> 6] >> (i & 63) & 1 == 1
    }

    /// Set local voxel `i`.
    #[inline]
    pub fn set(&mut self, i: usize) {
        self.0[i >> 6] |= 1 << (i & 63);
    }

    /// Voxel-wise and.
    #[inline]
    pub fn and(&self, o: &Mask512) -> Mask512 {
        Mask512(std::array::from_fn(|z| self.0[z] & o.0[z]))
    }

    /// Voxel-wise and-not.
    #[inline]
    pub fn and_not(&self, o: &Mask512) -> Mask512 {
        Mask512(std::array::from_fn(|z| self.0[z] & !o.0[z]))
    }

    /// Voxel-wise or.
    #[inline]
    pub fn or(&self, o: &Mask512) -> Mask512 {
        Mask512(std::array::from_fn(|z| self.0[z] | o.0[z]))
    }

    /// The voxels on one face of the brick.
    pub fn face(face: Face) -> Mask512 {
        match (face.axis, face.side) {
            (0, 0) => Mask512([X0; 8]),
            (0, _) => Mask512([X7; 8]),
            (1, 0) => Mask512([Y0; 8]),
            (1, _) => Mask512([Y7; 8]),
            (_, s) => {
                let mut m = Mask512::EMPTY;
                m.0[if s == 0 { 0 } else { 7 }] = u64::MAX;
                m
            }
        }
    }

    /// Move the voxels on `face` across to the opposite face, as the neighbouring brick sees them.
    pub fn across(&self, face: Face) -> Mask512 {
        let f = self.and(&Mask512::face(face));
        match (face.axis, face.side) {
            (0, 0) => Mask512(f.0.map(|w| w << 7)),
            (0, _) => Mask512(f.0.map(|w| w >> 7)),
            (1, 0) => Mask512(f.0.map(|w| w << 56)),
            (1, _) => Mask512(f.0.map(|w| w >> 56)),
            (_, 0) => {
                let mut m = Mask512::EMPTY;
                m.0[7] = f.0[0];
                m
            }
            (_, _) => {
                let mut m = Mask512::EMPTY;
                m.0[0] = f.0[7];
                m
            }
        }
    }

    /// Grow by one voxel along x, taking in the bits that cross from the low and high
    /// neighbours (their voxels at local x = 7 and x = 0 respectively).
    #[inline]
    pub fn dilate_x(&self, low: &Mask512, high: &Mask512) -> Mask512 {
        Mask512(std::array::from_fn(|z| {
            let w = self.0[z];
            w | ((w << 1) & !X0) | ((w >> 1) & !X7) | ((low.0[z] & X7) >> 7) | ((high.0[z] & X0) << 7)
        }))
    }

    /// Grow by one voxel along y, with the low and high neighbours along y.
    #[inline]
    pub fn dilate_y(&self, low: &Mask512, high: &Mask512) -> Mask512 {
        Mask512(std::array::from_fn(|z| {
            let w = self.0[z];
            w | (w << 8) | (w >> 8) | (low.0[z] >> 56) | (high.0[z] << 56)
        }))
    }

    /// Grow by one voxel along z, with the low and high neighbours along z.
    #[inline]
    pub fn dilate_z(&self, low: &Mask512, high: &Mask512) -> Mask512 {
        Mask512(std::array::from_fn(|z| {
            let below = if z == 0 { low.0[7] } else { self.0[z - 1] };
            let above = if z == 7 { high.0[0] } else { self.0[z + 1] };
            self.0[z] | below | above
        }))
    }

    /// Grow by one voxel in the six face directions, staying inside the brick.
    #[inline]
    pub fn dilate6_inside(&self) -> Mask512 {
        let e = Mask512::EMPTY;
        let x = self.dilate_x(&e, &e);
        let y = self.dilate_y(&e, &e);
        let z = self.dilate_z(&e, &e);
        x.or(&y).or(&z)
    }

    /// Flood `self` through the voxels of `open` (6-connected) until nothing changes.
    pub fn flood_within(&self, open: &Mask512) -> Mask512 {
        let mut cur = self.and(open);
        loop {
            let next = cur.dilate6_inside().and(open);
            if next == cur {
                return cur;
            }
            cur = next;
        }
    }

    /// Iterate the local indices of set voxels in increasing order.
    pub fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.0.iter().enumerate().flat_map(|(z, &w)| {
            let mut w = w;
            std::iter::from_fn(move || {
                if w == 0 {
                    return None;
                }
                let b = w.trailing_zeros() as usize;
                w &= w - 1;
                Some(z * 64 + b)
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::local_index;

    fn single(x: u32, y: u32, z: u32) -> Mask512 {
        let mut m = Mask512::EMPTY;
        m.set(local_index(x, y, z));
        m
    }

    #[test]
    fn dilation_matches_coordinates() {
        let e = Mask512::EMPTY;
        let m = single(3, 4, 5);
        let d = m.dilate_x(&e, &e);
        assert_eq!(d.count(), 3);
        assert!(d.get(local_index(2, 4, 5)) && d.get(local_index(4, 4, 5)));
        let d = m.dilate_y(&e, &e);
        assert!(d.get(local_index(3, 3, 5)) && d.get(local_index(3, 5, 5)));
        let d = m.dilate_z(&e, &e);
        assert!(d.get(local_index(3, 4, 4)) && d.get(local_index(3, 4, 6)));
        // No wrap-around between rows.
        let d = single(7, 0, 0).dilate_x(&e, &e);
        assert_eq!(d.count(), 2);
        assert!(!d.get(local_index(0, 1, 0)));
    }

    #[test]
    fn neighbours_feed_across_faces() {
        let e = Mask512::EMPTY;
        let low = single(7, 2, 3);
        assert!(e.dilate_x(&low, &e).get(local_index(0, 2, 3)));
        let high = single(0, 2, 3);
        assert!(e.dilate_x(&e, &high).get(local_index(7, 2, 3)));
        assert!(e.dilate_y(&single(2, 7, 3), &e).get(local_index(2, 0, 3)));
        assert!(e.dilate_y(&e, &single(2, 0, 3)).get(local_index(2, 7, 3)));
        assert!(e.dilate_z(&single(2, 3, 7), &e).get(local_index(2, 3, 0)));
        assert!(e.dilate_z(&e, &single(2, 3, 0)).get(local_index(2, 3, 7)));
    }

    #[test]
    fn across_maps_faces() {
        for f in Face::ALL {
            let a = Mask512::face(f).across(f);
            assert_eq!(a, Mask512::face(f.opposite()), "{f:?}");
        }
        let m = single(7, 5, 6).across(Face { axis: 0, side: 1 });
        assert_eq!(m, single(0, 5, 6));
    }

    #[test]
    fn flood_stops_at_walls() {
        // A wall at local x = 4 splits the brick.
        let mut wall = Mask512::EMPTY;
        for y in 0..8 {
            for z in 0..8 {
                wall.set(local_index(4, y, z));
            }
        }
        let open = Mask512::FULL.and_not(&wall);
        let r = single(0, 0, 0).flood_within(&open);
        assert_eq!(r.count(), 4 * 64);
        assert!(!r.get(local_index(5, 0, 0)));
        assert_eq!(r.iter().count(), 256);
    }
}
