//! Deciding an object's voxels block by block: a model of `b` per block, a walk of each column's
//! crossings against it, and splitting where the model cannot decide.

use std::cell::OnceCell;

use super::*;

/// A box of voxels `[lo, hi)`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Block {
    pub(super) lo: [i64; 3],
    pub(super) hi: [i64; 3],
}

impl Block {
    pub(super) fn extent(&self, a: usize) -> i64 {
        self.hi[a] - self.lo[a]
    }

    pub(super) fn volume(&self) -> i64 {
        (0..3).map(|a| self.extent(a)).product()
    }

    /// The box of the points where the block's voxels are sampled: centres, moved by the
    /// columns' nudge.
    pub(super) fn samples(&self) -> (DVec3, DVec3) {
        let nudge = DVec3::new(NUDGE.x, NUDGE.y, 0.0);
        let lo = DVec3::new(self.lo[0] as f64, self.lo[1] as f64, self.lo[2] as f64) + 0.5 + nudge;
        let hi = DVec3::new(self.hi[0] as f64, self.hi[1] as f64, self.hi[2] as f64) - 0.5 + nudge;
        (lo, hi)
    }

    /// Push the halves of a block no model could be made for, or its voxels when few.
    pub(super) fn refine(&self, stack: &mut Vec<Block>) {
        if self.volume() > SMALL_BLOCK {
            return self.split([true; 3], stack);
        }
        for x in self.lo[0]..self.hi[0] {
            for y in self.lo[1]..self.hi[1] {
                for z in self.lo[2]..self.hi[2] {
                    stack.push(Block {
                        lo: [x, y, z],
                        hi: [x + 1, y + 1, z + 1],
                    });
                }
            }
        }
    }

    /// Push the halves of the block along the axes in `axes` whose extent is above one.
    pub(super) fn split(&self, axes: [bool; 3], stack: &mut Vec<Block>) {
        let mut parts = vec![*self];
        for (a, &split) in axes.iter().enumerate() {
            if !split || self.extent(a) < 2 {
                continue;
            }
            let mid = self.lo[a] + self.extent(a) / 2;
            parts = parts
                .into_iter()
                .flat_map(|p| {
                    let (mut l, mut h) = (p, p);
                    l.hi[a] = mid;
                    h.lo[a] = mid;
                    [l, h]
                })
                .collect();
        }
        stack.extend(parts);
    }
}

/// What every block of one object needs.
pub(super) struct Context<'a> {
    pub(super) obj: &'a WindingObject,
    pub(super) crossings: &'a Crossings,
    pub(super) surface: &'a [(u64, Mask512)],
    pub(super) grid: &'a Grid,
}

impl Context<'_> {
    /// Whether voxel `(x, y, z)` is a surface voxel of the scene.
    pub(super) fn is_surface(&self, x: i64, y: i64, z: i64) -> bool {
        let v = [x as u32, y as u32, z as u32];
        let (b, local) = split_voxel(v);
        let key = self.grid.brick_key(b);
        match self.surface.binary_search_by_key(&key, |s| s.0) {
            Ok(i) => self.surface[i].1.get(local),
            Err(_) => false,
        }
    }
}

/// What the blocks of one tile look up, found once for the tile: the crossings of each of its
/// rows of columns, and the scene's surface voxels over its bricks as an array. Searching the
/// object's crossings and the scene's sorted bricks block by block, voxel by voxel, took a
/// quarter of the fill's time on open CAD objects.
pub(super) struct Tile<'a> {
    pub(super) ctx: &'a Context<'a>,
    tile: Block,
    /// For each x of the tile, its columns' crossings.
    rows: Vec<&'a [(u64, f64, i8)]>,
    /// Built on the first question: tiles far from the level set never ask.
    surface: OnceCell<(
        /* first brick */ [i64; 3],
        /* bricks */ [i64; 3],
        Vec<Mask512>,
    )>,
}

impl<'a> Tile<'a> {
    pub(super) fn new(ctx: &'a Context<'a>, tile: Block) -> Tile<'a> {
        let rows = (tile.lo[0]..tile.hi[0])
            .map(|x| ctx.crossings.row(x, tile.lo[1], tile.hi[1]))
            .collect();
        Tile {
            ctx,
            tile,
            rows,
            surface: OnceCell::new(),
        }
    }

    /// The crossings of columns `(x, y0..y1)` of the tile, in order.
    pub(super) fn row(&self, x: i64, y0: i64, y1: i64) -> &'a [(u64, f64, i8)] {
        row_of(self.rows[(x - self.tile.lo[0]) as usize], x, y0, y1)
    }

    /// Whether voxel `(x, y, z)`, which must lie in the tile, is a surface voxel of the scene.
    pub(super) fn is_surface(&self, x: i64, y: i64, z: i64) -> bool {
        let (lo, n, masks) = self.surface.get_or_init(|| self.surface_masks());
        let v = [x, y, z];
        let b: [i64; 3] = std::array::from_fn(|a| (v[a] >> BRICK_SHIFT) - lo[a]);
        debug_assert!((0..3).all(|a| (0..n[a]).contains(&b[a])), "voxel outside its tile");
        let (_, local) = split_voxel(v.map(|c| c as u32));
        masks[((b[0] * n[1] + b[1]) * n[2] + b[2]) as usize].get(local)
    }

    fn surface_masks(&self) -> ([i64; 3], [i64; 3], Vec<Mask512>) {
        let lo = self.tile.lo.map(|c| c >> BRICK_SHIFT);
        let n: [i64; 3] = std::array::from_fn(|a| ((self.tile.hi[a] - 1) >> BRICK_SHIFT) + 1 - lo[a]);
        let mut masks = vec![Mask512::EMPTY; (n[0] * n[1] * n[2]) as usize];
        let (surface, grid) = (self.ctx.surface, self.ctx.grid);
        for i in 0..n[0] {
            for j in 0..n[1] {
                // A column of bricks has consecutive keys.
                let first = grid.brick_key([(lo[0] + i) as u32, (lo[1] + j) as u32, lo[2] as u32]);
                let end = first + n[2] as u64;
                let start = surface.partition_point(|s| s.0 < first);
                for (key, mask) in surface[start..].iter().take_while(|s| s.0 < end) {
                    masks[((i * n[1] + j) * n[2]) as usize + (key - first) as usize] = *mask;
                }
            }
        }
        (lo, n, masks)
    }
}

/// Blocks of fewer voxels are not first tested against the triangles' areas: that test
/// decides blocks far from the object, which are found while blocks are large, and costs a
/// walk of the triangles' tree.
pub(super) const AREA_TEST_VOXELS: i64 = 512;

/// Blocks of at most this many voxels that cannot get a model are done voxel by voxel.
pub(super) const SMALL_BLOCK: i64 = 8;

/// When a model leaves at most this many voxels of its block undecided, they are done one by
/// one: splitting the block would cost more models than that.
pub(super) const DIRECT_VOXELS: usize = 4;

/// Decide one block, or split it onto `stack`.
pub(super) fn decide(tile: &Tile, block: Block, runs: &mut Runs, stack: &mut Vec<Block>) {
    let ctx = tile.ctx;
    let obj = ctx.obj;
    let (lo, hi) = block.samples();
    // Far from a soup's triangles, their areas alone prove it outside: no model needed.
    let (c, radius) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
    if block.volume() >= AREA_TEST_VOXELS && !obj.area.may_reach(c, radius, THRESHOLD) {
        return;
    }
    // No model can be made for a ball a boundary edge comes into (found in the edges' tree,
    // not by the model's sum over all of them): cut the block, down to voxels (a single voxel
    // goes on to be decided: cut, it would be itself again, forever).
    if block.volume() > 1 && obj.edge_within(c, radius) {
        block.refine(stack);
        return;
    }
    let columns = block.extent(0) > 1 || block.extent(1) > 1;
    // A strip inside the block makes `b` jump there: take the strips hanging down where those
    // hanging up cut the block, and where both do, cut across x and y until one column
    // remains, whose vertical line meets no strip.
    let down = columns && obj.strip_meets(lo, hi, false);
    if down && obj.strip_meets(lo, hi, true) {
        block.refine(stack);
        return;
    }
    let single = !columns && block.extent(2) == 1;
    let model = if single {
        if tile.is_surface(block.lo[0], block.lo[1], block.lo[2]) {
            return;
        }
        // The whole boundary summed. (The triangles near the voxel summed exactly and the rest
        // bounded by their areas decided none of 120,000 single voxels of a soup of loose
        // triangles, nor of 80,000 of a scanned monastery, since blocks are cut only where a
        // boundary edge comes near: not tried.)
        Linear {
            at: lo,
            b: obj.boundary_part(lo, false),
            slope: DVec3::ZERO,
            curvature: 0.0,
            error: 0.0,
            down: false,
        }
    } else {
        let Some((b, slope, h)) = obj.taylor(c, radius, down) else {
            block.refine(stack);
            return;
        };
        Linear {
            at: c,
            b,
            slope,
            curvature: 0.5 * h,
            error: SLACK,
            down,
        }
    };
    let mut open = Undecided::default();
    scan(tile, block, &model, runs, &mut open);
    // Decided voxels keep their runs (a part that decides them again adds the same runs);
    // the undecided ones go on alone when few, else the octants that hold them.
    if open.count == 0 {
        return;
    }
    if open.count <= DIRECT_VOXELS {
        stack.extend(open.first[..open.count].iter().map(|&v| Block {
            lo: v,
            hi: v.map(|c| c + 1),
        }));
        return;
    }
    let mut parts = Vec::with_capacity(8);
    block.split([true; 3], &mut parts);
    for part in parts {
        let mut octant = 0;
        for a in 0..3 {
            if part.lo[a] > block.lo[a] {
                octant |= 1 << a;
            }
        }
        if open.octants & (1 << octant) != 0 {
            stack.push(part);
        }
    }
}

/// `b` over a block: `b + slope · (p − at)`, give or take `curvature · |p − at|² + error`
/// (Taylor's remainder with `curvature` half a bound on the Hessian over the block's ball); of
/// the strips hanging `down` (then `w = S − S_total + b` in each column) or up (`w = S + b`).
/// The remainder is taken at each point rather than at the ball's rim: voxels near the centre
/// are decided where the block as a whole is not.
pub(super) struct Linear {
    pub(super) at: DVec3,
    pub(super) b: f64,
    pub(super) slope: DVec3,
    pub(super) curvature: f64,
    pub(super) error: f64,
    pub(super) down: bool,
}

impl Linear {
    /// The range of `b` over the vertical segment at `(x, y)` from `z0` to `z1` (grid units).
    #[inline]
    pub(super) fn range(&self, x: f64, y: f64, z0: f64, z1: f64) -> (f64, f64) {
        let (dx, dy) = (x - self.at.x, y - self.at.y);
        let base = self.b + self.slope.x * dx + self.slope.y * dy;
        let (d0, d1) = (z0 - self.at.z, z1 - self.at.z);
        let (u, v) = (self.slope.z * d0, self.slope.z * d1);
        // The farthest point of the segment from `at` is one of its ends.
        let error = self.curvature * (dx * dx + dy * dy + (d0 * d0).max(d1 * d1)) + self.error;
        (base + u.min(v) - error, base + u.max(v) + error)
    }
}

/// Whether whole number `s` plus any `b` in `[b_lo, b_hi]` is inside (`Some(true)`), outside
/// (`Some(false)`) or either.
#[inline]
pub(super) fn side(s: i32, b_lo: f64, b_hi: f64) -> Option<bool> {
    let (w_lo, w_hi) = (s as f64 + b_lo, s as f64 + b_hi);
    if w_lo >= THRESHOLD || w_hi <= -THRESHOLD {
        Some(true)
    } else if w_hi < THRESHOLD && w_lo > -THRESHOLD {
        Some(false)
    } else {
        None
    }
}

/// Decide every voxel of `block` given the model of `b` there, adding its inside runs.
pub(super) fn scan(tile: &Tile, block: Block, b: &Linear, runs: &mut Runs, open: &mut Undecided) {
    let (z0, z1) = (block.lo[2], block.hi[2]);
    let centre = |k: i64| k as f64 + 0.5;
    for x in block.lo[0]..block.hi[0] {
        let row = tile.row(x, block.lo[1], block.hi[1]);
        let mut at = 0;
        let px = centre(x) + NUDGE.x;
        for y in block.lo[1]..block.hi[1] {
            let key = (x as u64) << 32 | y as u64;
            let start = at;
            while at < row.len() && row[at].0 == key {
                at += 1;
            }
            let col = &row[start..at];
            let py = centre(y) + NUDGE.y;
            // Walk the column: S below the first centre, then segment by segment; with strips
            // hanging down, the crossings above count instead, negated.
            let mut s: i32 = if b.down {
                -col.iter().map(|c| c.2 as i32).sum::<i32>()
            } else {
                0
            };
            let mut c = 0;
            while c < col.len() && col[c].1 < centre(z0) {
                s += col[c].2 as i32;
                c += 1;
            }
            let mut k = z0;
            while k < z1 {
                // Voxels k.. up to the first whose centre lies above the next crossing share S.
                let next = if c < col.len() {
                    ((col[c].1 - 0.5).floor() as i64 + 1).clamp(k, z1)
                } else {
                    z1
                };
                if next > k {
                    let (b_lo, b_hi) = b.range(px, py, centre(k), centre(next - 1));
                    match side(s, b_lo, b_hi) {
                        Some(true) => push_run(runs, x, y, k, next),
                        Some(false) => {}
                        None => {
                            // Voxel by voxel: surface voxels need no side, the rest may each
                            // be decided where the whole segment is not.
                            for z in k..next {
                                let (b_lo, b_hi) = b.range(px, py, centre(z), centre(z));
                                match side(s, b_lo, b_hi) {
                                    Some(true) => push_run(runs, x, y, z, z + 1),
                                    Some(false) => {}
                                    None if tile.is_surface(x, y, z) => {}
                                    None => open.add(&block, [x, y, z]),
                                }
                            }
                        }
                    }
                    k = next;
                }
                if c < col.len() {
                    s += col[c].2 as i32;
                    c += 1;
                }
            }
        }
    }
}

/// The voxels of a block its model left undecided: how many, the first few, and which of
/// its octants hold any.
#[derive(Default)]
pub(super) struct Undecided {
    pub(super) count: usize,
    pub(super) first: [[i64; 3]; DIRECT_VOXELS],
    pub(super) octants: u8,
}

impl Undecided {
    pub(super) fn add(&mut self, block: &Block, v: [i64; 3]) {
        if self.count < DIRECT_VOXELS {
            self.first[self.count] = v;
        }
        self.count += 1;
        let mut octant = 0;
        for (a, &c) in v.iter().enumerate() {
            if c >= block.lo[a] + block.extent(a) / 2 && block.extent(a) > 1 {
                octant |= 1 << a;
            }
        }
        self.octants |= 1 << octant;
    }
}

pub(super) fn push_run(runs: &mut Runs, x: i64, y: i64, z0: i64, z1: i64) {
    runs.push(((x as u64) << 32 | y as u64, z0 as u32, z1 as u32));
}
