//! Triangle–box overlap by the separating axis theorem: 13 axes, closed boxes.
//!
//! The axes are the three box face normals, the triangle normal and the nine cross products of
//! box edges with triangle edges (Akenine-Möller 2001; Sagardia et al. 2008, §3.2). Projections
//! that only touch count as overlap, so a triangle lying on a face shared by two voxels touches
//! both.

use glam::DVec3;

/// A triangle prepared for many box tests: its edges and normal are computed once.
#[derive(Clone, Copy, Debug)]
pub struct SatTriangle {
    /// The vertices.
    pub v: [DVec3; 3],
    /// Edges `f0 = v1 - v0`, `f1 = v2 - v1`, `f2 = v0 - v2`.
    pub f: [DVec3; 3],
    /// Normal `f0 × f1` (not normalised).
    pub n: DVec3,
}

impl SatTriangle {
    /// Prepare a triangle.
    pub fn new(v: [DVec3; 3]) -> SatTriangle {
        let f = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
        SatTriangle {
            v,
            f,
            n: f[0].cross(f[1]),
        }
    }

    /// Whether the triangle touches the closed box with this centre and half extents.
    #[inline]
    pub fn overlaps_box(&self, center: DVec3, half: DVec3) -> bool {
        let v0 = self.v[0] - center;
        let v1 = self.v[1] - center;
        let v2 = self.v[2] - center;

        // Box face normals: the triangle's bounding box against the box.
        for a in 0..3 {
            let (lo, hi) = min_max3(v0[a], v1[a], v2[a]);
            if lo > half[a] || hi < -half[a] {
                return false;
            }
        }

        // Triangle normal: the box corner farthest along n against the plane.
        let d = self.n.dot(v0);
        let r = half.dot(self.n.abs());
        if d > r || d < -r {
            return false;
        }

        // Nine cross axes e_a × f_j. For each, two of the three vertices project alike.
        for (j, f) in self.f.iter().enumerate() {
            // The vertex that is not on edge j projects apart from the two that are.
            let (p, q) = match j {
                0 => (v0, v2),
                1 => (v1, v0),
                _ => (v2, v1),
            };
            // e_x × f = (0, -f.z, f.y)
            let ax = DVec3::new(0.0, -f.z, f.y);
            if separated(ax, p, q, half) {
                return false;
            }
            // e_y × f = (f.z, 0, -f.x)
            let ay = DVec3::new(f.z, 0.0, -f.x);
            if separated(ay, p, q, half) {
                return false;
            }
            // e_z × f = (-f.y, f.x, 0)
            let az = DVec3::new(-f.y, f.x, 0.0);
            if separated(az, p, q, half) {
                return false;
            }
        }
        true
    }

    /// Whether the triangle touches the closed unit voxel `[i, i+1] × [j, j+1] × [k, k+1]`, with
    /// the triangle given in grid units.
    #[inline]
    pub fn overlaps_voxel(&self, v: [i64; 3]) -> bool {
        let c = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) + 0.5;
        self.overlaps_box(c, DVec3::splat(0.5))
    }
}

/// Whether `axis` separates the triangle (two distinct projections, from `p` and `q`) from the
/// box of half extents `half` centred at the origin.
#[inline(always)]
fn separated(axis: DVec3, p: DVec3, q: DVec3, half: DVec3) -> bool {
    let a = axis.dot(p);
    let b = axis.dot(q);
    let r = half.dot(axis.abs());
    a.min(b) > r || a.max(b) < -r
}

#[inline(always)]
fn min_max3(a: f64, b: f64, c: f64) -> (f64, f64) {
    (a.min(b).min(c), a.max(b).max(c))
}

/// Whether triangle `t` touches the closed box with centre `center` and half extents `half`.
pub fn triangle_box_overlap(t: [DVec3; 3], center: DVec3, half: DVec3) -> bool {
    SatTriangle::new(t).overlaps_box(center, half)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn touching_faces_edges_and_corners_count() {
        let t = SatTriangle::new([
            DVec3::new(1.0, 0.2, 0.2),
            DVec3::new(1.0, 0.8, 0.2),
            DVec3::new(1.0, 0.2, 0.8),
        ]);
        // Lies on the face x = 1 shared by voxels 0 and 1.
        assert!(t.overlaps_voxel([0, 0, 0]));
        assert!(t.overlaps_voxel([1, 0, 0]));
        assert!(!t.overlaps_voxel([2, 0, 0]));
        // A triangle whose only common point with the voxel is a corner.
        let c = SatTriangle::new([
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(2.0, 1.0, 1.5),
            DVec3::new(1.5, 2.0, 2.0),
        ]);
        assert!(c.overlaps_voxel([0, 0, 0]));
    }

    #[test]
    fn near_miss_past_an_edge_of_the_box() {
        // Bounding boxes overlap; the triangle passes beside the box's edge at x = y = 1.
        let t = SatTriangle::new([
            DVec3::new(2.6, -0.5, 0.5),
            DVec3::new(-0.5, 2.6, 0.5),
            DVec3::new(-0.5, 2.6, 0.6),
        ]);
        assert!(!t.overlaps_voxel([0, 0, 0]));
        let t = SatTriangle::new([
            DVec3::new(2.4, -0.5, 0.5),
            DVec3::new(-0.5, 2.4, 0.5),
            DVec3::new(-0.5, 2.4, 0.6),
        ]);
        assert!(t.overlaps_voxel([0, 0, 0]));
    }
}
