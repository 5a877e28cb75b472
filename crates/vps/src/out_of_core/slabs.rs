//! Slabs of brick planes: how many fit in the memory limit, and what each slab needs to decide
//! its inside (the scene's outside labels, or each object's columns).

use super::*;

/// The memory a slab takes, from the surface bricks of each brick plane.
pub(super) struct SlabEstimate<'a> {
    pub(super) per_plane: &'a [u64],
    pub(super) plane: u64,
    pub(super) halo: u32,
    pub(super) fill: Fill,
    pub(super) read_bytes: u64,
    /// Whether the slabs' signed distances are computed.
    pub(super) distances: bool,
}

impl SlabEstimate<'_> {
    pub(super) fn surface(&self, r: Range<u32>) -> u64 {
        self.per_plane[r.start as usize..r.end as usize].iter().sum()
    }

    /// An upper estimate of the bytes of slab `r` in pass 3 (the heaviest).
    pub(super) fn bytes(&self, r: Range<u32>) -> u64 {
        let n = self.per_plane.len() as u32;
        let wide = r.start.saturating_sub(self.halo)..(r.end + self.halo).min(n);
        let with_halo = self.surface(wide.clone());
        let own = self.surface(r.clone());
        let reach = 2 * self.halo as u64 + 1;
        let near = ((wide.end - wide.start) as u64 * self.plane).min(with_halo * reach * reach * reach);
        let fill = own * FILL_BRICK_BYTES
            + match self.fill {
                Fill::Objects | Fill::Winding => CROSSINGS_BYTES,
                Fill::Scene => 0,
            };
        // A slab's distances are made while the next slab's values are: count both, each by
        // its own bricks near the surface.
        let own_near = ((r.end - r.start) as u64 * self.plane).min(own * reach * reach * reach);
        let distances = if self.distances {
            2 * own_near * DISTANCE_BRICK_BYTES
        } else {
            0
        };
        self.read_bytes + with_halo * SURFACE_BRICK_BYTES * 2 + near * NEAR_BRICK_BYTES + fill + distances
    }

    /// Cut the planes into slabs whose estimates fit `budget`, each as thick as it can be;
    /// at least a few slabs, so that progress moves.
    pub(super) fn plan(&self, budget: u64, max_planes: Option<u32>) -> Result<Vec<Range<u32>>, GenerateError> {
        let n = self.per_plane.len() as u32;
        let max_planes = max_planes.unwrap_or(n.div_ceil(8).max(CHUNK_BRICKS)).max(1);
        let mut slabs = Vec::new();
        let mut a = 0;
        while a < n {
            let need = self.bytes(a..a + 1);
            if need > budget {
                return Err(GenerateError::MemoryLimit {
                    limit: budget,
                    need,
                    what: format!("one brick plane of the grid (x = {a}), the thinnest slab,"),
                });
            }
            let mut b = a + 1;
            while b < n && b - a < max_planes && self.bytes(a..b + 1) <= budget {
                b += 1;
            }
            slabs.push(a..b);
            a = b;
        }
        Ok(slabs)
    }
}

/// What pass 3 needs to decide each slab's inside.
pub(super) enum SlabFill {
    /// `Fill::Scene`: which labels of each slab's components are outside.
    Scene(SlabLabels),
    /// `Fill::Objects`: the closed objects, to cast their columns slab by slab.
    Objects(ObjectColumns),
}

/// Which component labels of each slab are outside, after uniting them across slabs.
pub(super) struct SlabLabels {
    /// First global label of each slab.
    pub(super) first: Vec<u32>,
    /// Whether each global label is outside.
    pub(super) outside: Vec<bool>,
}

impl SlabLabels {
    pub(super) fn is_outside(&self, slab: usize, label: u32) -> bool {
        self.outside[(self.first[slab] + label) as usize]
    }
}

/// Pass 2 for `Fill::Scene`: label each slab's components, unite them across slab
/// boundaries, and mark those joined to voxel (0, 0, 0).
pub(super) fn scene_outside(
    slabs: &[Range<u32>],
    nb: [u32; 3],
    reader: &SurfaceReader,
    opts: &Bounded,
    cancelled: &(dyn Fn() -> bool + Sync),
) -> Result<SlabLabels, GenerateError> {
    let plane = nb[1] as u64 * nb[2] as u64;
    let done = AtomicU64::new(0);
    let total = slabs.len() as u64;
    (opts.progress)("fill", 0, total);
    // (label count, low face, high face, label of voxel (0, 0, 0) in slab 0)
    type Labelled = (u32, XFace, XFace, Option<u32>);
    let labelled: Vec<Result<Labelled, GenerateError>> = slabs
        .par_iter()
        .enumerate()
        .map(|(i, slab)| {
            if cancelled() {
                return Err(GenerateError::Cancelled);
            }
            let base = slab.start as u64 * plane;
            let sub: Vec<(u64, Mask512)> = reader
                .read(slab.clone())?
                .into_iter()
                .map(|(k, m)| (k - base, m))
                .collect();
            let comps = Components::label([slab.end - slab.start, nb[1], nb[2]], &sub);
            let origin = if i == 0 { comps.label_of([0, 0, 0]) } else { None };
            let out = (comps.count(), comps.x_face(0), comps.x_face(1), origin);
            let n = done.fetch_add(1, Ordering::Relaxed) + 1;
            (opts.progress)("fill", n, total);
            Ok(out)
        })
        .collect();
    let labelled: Vec<Labelled> = labelled.into_iter().collect::<Result<_, _>>()?;
    let mut first = Vec::with_capacity(slabs.len());
    let mut n = 0u32;
    for l in &labelled {
        first.push(n);
        n += l.0;
    }
    let mut uf = UnionFind::new(n as usize);
    for i in 1..labelled.len() {
        let (fa, fb) = (first[i - 1], first[i]);
        Components::unite_across(&labelled[i - 1].2, &labelled[i].1, |a, b| uf.union(fa + a, fb + b));
    }
    let outside = match labelled.first().and_then(|l| l.3) {
        Some(origin) => {
            let root = uf.find(origin);
            (0..n).map(|l| uf.find(l) == root).collect()
        }
        // Voxel (0, 0, 0) lies in the padding, so it is never a surface voxel.
        None => vec![false; n as usize],
    };
    Ok(SlabLabels { first, outside })
}

/// The objects of a mesh that have an inside, and their extents along x, for `Fill::Objects`
/// and `Fill::Winding` slab by slab.
pub(super) struct ObjectColumns {
    /// Index of each object with an inside, the brick planes its triangles span, and for the
    /// winding fill what it needs of the object besides its triangles.
    pub(super) solid: Vec<(usize, Range<u32>, Option<winding::WindingObject>)>,
    /// Objects that are not closed.
    pub(super) open: usize,
}

impl ObjectColumns {
    pub(super) fn new(
        grid: &Grid,
        mesh: &Mesh,
        fill: Fill,
        progress: &(dyn Fn(&str, u64, u64) + Sync),
    ) -> ObjectColumns {
        let nbx = grid.brick_dims()[0];
        let (done, total) = (AtomicU64::new(0), mesh.objects.len() as u64);
        progress("fill", 0, total);
        // Per object: whether it is closed, and its entry of `solid` if it has an inside.
        type Entry = (usize, Range<u32>, Option<winding::WindingObject>);
        let per: Vec<(bool, Option<Entry>)> = mesh
            .objects
            .par_iter()
            .enumerate()
            .map(|(i, o)| {
                progress("fill", done.fetch_add(1, Ordering::Relaxed) + 1, total);
                let tris = &mesh.triangles[o.triangles.clone()];
                let (closed, w) = if fill == Fill::Winding {
                    let w = winding::WindingObject::new(grid, tris);
                    (!w.is_open(), Some(w))
                } else {
                    (inside::is_closed(tris), None)
                };
                if !closed && w.is_none() {
                    return (false, None);
                }
                let (lo, hi) = match &w {
                    // Open objects' inside may reach beyond their triangles.
                    Some(w) => (w.columns().start as f64, w.columns().end as f64),
                    None => {
                        let (lo, hi) = crate::mesh::bounds_of(tris);
                        (grid.to_grid_units(lo).x, grid.to_grid_units(hi).x)
                    }
                };
                // Brick planes of the column centres the object spans, one more each side for
                // rounding; a wider range only costs a few empty loops.
                let b0 = ((lo - 1.0).floor().max(0.0) as u32 / 8).min(nbx);
                let b1 = (((hi + 1.0).ceil().max(0.0) as u32).div_ceil(8) + 1).min(nbx);
                (closed, Some((i, b0..b1, w)))
            })
            .collect();
        let open = per.iter().filter(|p| !p.0).count();
        ObjectColumns {
            solid: per.into_iter().filter_map(|p| p.1).collect(),
            open,
        }
    }

    /// The inside of the columns of `slab` (brick planes), and the winding fill's interface
    /// voxels (see [`winding::add_object_inside`]) of the columns of `halo` (the slab and the
    /// planes around it), one (object, brick plane of columns) at a time, in parallel: a large
    /// object spread over many planes keeps every core busy, and the crossings held stay those
    /// of one plane per thread. `surface` is the surface of `halo`, which the winding fill
    /// need not decide.
    pub(super) fn inside(
        &self,
        grid: &Grid,
        mesh: &Mesh,
        surface: &[(u64, Mask512)],
        slab: Range<u32>,
        halo: Range<u32>,
    ) -> (ObjectsInside, Vec<(u64, Mask512)>) {
        let tris_of = |s: usize| &mesh.triangles[mesh.objects[self.solid[s].0].triangles.clone()];
        // Only open objects have an interface, so only they are done in the halo.
        let open = |w: &Option<winding::WindingObject>| w.as_ref().is_some_and(|w| w.is_open());
        let planes_of = |r: &Range<u32>, w: &Option<winding::WindingObject>| {
            let wanted = if open(w) { &halo } else { &slab };
            wanted.start.max(r.start)..wanted.end.min(r.end)
        };
        // (entry of `solid`, brick plane, triangle) for every plane of columns a triangle's x
        // extent meets, with two voxels to spare (the winding fill looks one column beyond its
        // own), and (entry, plane, NONE) for every plane, so that planes an open object's
        // inside reaches beyond its triangles are done too. An open object's planes are one
        // group, keyed by its first plane.
        const NONE: u32 = u32::MAX;
        let mut items: Vec<(u32, u32, u32)> = self
            .solid
            .par_iter()
            .enumerate()
            .filter(|(_, (_, r, w))| !planes_of(r, w).is_empty())
            .flat_map_iter(|(i, (_, r, w))| {
                let planes = planes_of(r, w);
                // An open object is done in one piece over all its planes: its blocks then
                // start as wide as the tiles, not one brick plane of columns.
                let whole = open(w);
                let keys = if whole {
                    planes.start..planes.start + 1
                } else {
                    planes.clone()
                };
                let every = keys.clone().map(move |b| (i as u32, b, NONE));
                let reaching = tris_of(i).iter().enumerate().flat_map(move |(k, t)| {
                    let xs = t.map(|p| grid.to_grid_units(p).x);
                    let (lo, hi) = (xs[0].min(xs[1]).min(xs[2]) - 2.0, xs[0].max(xs[1]).max(xs[2]) + 2.0);
                    let (b0, b1) = if lo.is_finite() && hi.is_finite() {
                        (
                            ((lo.max(0.0) / 8.0) as u32).max(planes.start),
                            ((hi.max(0.0) / 8.0) as u32 + 1).min(planes.end),
                        )
                    } else {
                        (0, 0)
                    };
                    let reached = if whole && b0 < b1 { keys.clone() } else { b0..b1 };
                    reached.map(move |b| (i as u32, b, k as u32))
                });
                every.chain(reaching)
            })
            .collect();
        items.par_sort_unstable();
        let groups: Vec<&[(u32, u32, u32)]> = items.chunk_by(|a, b| (a.0, a.1) == (b.0, b.1)).collect();
        let inside = groups
            .par_iter()
            .fold(
                || (ObjectsInside::default(), Vec::new()),
                |(mut out, mut interface), group| {
                    let tris = tris_of(group[0].0 as usize);
                    let own: Vec<Triangle> = group
                        .iter()
                        .filter(|&&(_, _, k)| k != NONE)
                        .map(|&(_, _, k)| tris[k as usize])
                        .collect();
                    let (_, r, object) = &self.solid[group[0].0 as usize];
                    let x0 = group[0].1 * 8;
                    let x1 = (x0 + 8).min(grid.dims[0]);
                    let mut halo_only = ObjectsInside::default();
                    let into = if slab.contains(&group[0].1) {
                        &mut out
                    } else {
                        &mut halo_only
                    };
                    match object {
                        Some(w) if w.is_open() => {
                            let planes = planes_of(r, object);
                            let columns = winding::Columns {
                                decide: planes.start * 8..(planes.end * 8).min(grid.dims[0]),
                                keep: slab.start * 8..(slab.end * 8).min(grid.dims[0]),
                            };
                            winding::add_object_inside(grid, &own, w, surface, columns, &mut out, &mut interface)
                        }
                        Some(w) => {
                            let columns = winding::Columns::all(x0..x1);
                            winding::add_object_inside(grid, &own, w, surface, columns, into, &mut interface)
                        }
                        None => inside::add_closed_object_columns(grid, &own, x0..x1, inside::Rule::Parity, into),
                    }
                    (out, interface)
                },
            )
            .reduce(
                || (ObjectsInside::default(), Vec::new()),
                |(mut a, mut fa), (b, fb)| {
                    a.merge(b);
                    fa.extend(fb);
                    (a, fa)
                },
            );
        let (inside, interface) = inside;
        (inside.finish(), union_by_key(interface))
    }
}
