//! Drawing a textured plane into a frame, block by block.
//!
//! Patterns are cut into *parts* of one colour, each a convex set minus at
//! most one axis-aligned box (its hole). A group of pixels (a block, or one
//! pixel) whose corners all fall in the same part, and whose corners' bounding
//! box misses the part's hole, lies entirely in the part: its footprint on the
//! plane is the quadrilateral of its corners (up to the lens distortion's
//! curvature over a few pixels, covered by a small margin).
//!
//! The rectangle around the plane's outline is cut into square blocks. Only
//! blocks that are not uniform, or that touch a block of another colour, are
//! rendered per pixel, blurred and written; uniform blocks surrounded by their
//! own colour are written as a constant, or left alone when they show the
//! background (the frame already holds it, blurred).

use std::sync::OnceLock;

use super::raster::{PixelRect, PlaneInCamera, UndistortionMap, luma, quantise, to_fixed};

/// Sample positions inside a pixel (fractions of its side from the top-left
/// corner) for pixels that straddle a colour boundary: 8 samples on an
/// "n-rooks" pattern (one per row and per column of an 8 x 8 grid), so an
/// axis-aligned edge, the common case for a marker, is resolved to 1/8 px.
const SAMPLES: [(f64, f64); 8] = {
    const ROWS: [usize; 8] = [2, 5, 0, 7, 3, 6, 1, 4];
    let mut out = [(0.0, 0.0); 8];
    let mut k = 0;
    while k < 8 {
        out[k] = ((k as f64 + 0.5) / 8.0, (ROWS[k] as f64 + 0.5) / 8.0);
        k += 1;
    }
    out
};

/// Part value of rays that miss the plane (or see its hidden side).
pub(super) const MISS: u32 = u32::MAX;

/// A pattern on a plane, cut into parts of constant colour.
pub(super) trait PlanarPattern {
    /// The part containing plane point `(a, b)` (m, along the plane's x and y
    /// axes); values below [`PlanarPattern::part_count`].
    fn part(&self, a: f64, b: f64) -> u32;
    /// Number of parts.
    fn part_count(&self) -> u32;
    /// Colour of a part (0..255 per channel, sRGB), `None` where the plane
    /// is transparent (outside its outline).
    fn colour(&self, part: u32) -> Option<[f32; 3]>;
    /// The box `[a0, a1, b0, b1]` (m) cut out of a part, if any: the part is a
    /// convex set minus this box.
    fn hole(&self, part: u32) -> Option<[f64; 4]>;
    /// A part whose colour covers all of `bounds` (`[a0, a1, b0, b1]`, m),
    /// when the whole box has one colour (it may span several parts).
    fn colour_in_box(&self, bounds: [f64; 4]) -> Option<u32>;
}

/// Whether two boxes `[a0, a1, b0, b1]` are disjoint.
#[inline]
pub(super) fn disjoint(p: [f64; 4], q: [f64; 4]) -> bool {
    p[1] < q[0] || p[0] > q[1] || p[3] < q[2] || p[2] > q[3]
}

/// Whether box `inner` lies inside box `outer`.
#[inline]
pub(super) fn inside(inner: [f64; 4], outer: [f64; 4]) -> bool {
    inner[0] >= outer[0] && inner[1] <= outer[1] && inner[2] >= outer[2] && inner[3] <= outer[3]
}

/// Whether `(a, b)` lies in the box `[a0, a1, b0, b1]` (edges included).
#[inline]
pub(super) fn in_box(a: f64, b: f64, [a0, a1, b0, b1]: [f64; 4]) -> bool {
    a >= a0 && a <= a1 && b >= b0 && b <= b1
}

/// Where the frame is drawn: its bytes (all rows, or the rows from `row0`
/// on), the noise for each byte of the frame, its width.
pub(super) struct Target<'a> {
    /// The frame's rows from `row0` on, `C` bytes per pixel.
    pub data: &'a mut [u8],
    /// Fixed-point noise for every byte of the whole frame.
    pub noise: &'a [i16],
    /// Frame width (px).
    pub image_width: usize,
    /// The frame row that `data` starts with.
    pub row0: usize,
}

impl Target<'_> {
    /// Quantises `fixed` with its noise into the frame from pixel `(x, y)` on.
    #[inline]
    fn write(&mut self, x: usize, y: usize, channels: usize, fixed: &[i16]) {
        let start = (y * self.image_width + x) * channels;
        let local = start - self.row0 * self.image_width * channels;
        quantise(fixed, &self.noise[start..start + fixed.len()], &mut self.data[local..local + fixed.len()]);
    }
}

/// The inputs shared by every frame.
pub(super) struct Scene<'a> {
    /// Undistorted rays at the pixel corners.
    pub map: &'a UndistortionMap,
    /// The unblurred background, `C` floats per pixel.
    pub background: &'a [f32],
    /// The blur kernel (odd length; one tap for no blur).
    pub kernel: &'a [f32],
}

/// What the renderer knows of a block.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Block {
    /// One colour class (0 = background).
    Uniform(u16),
    /// Several parts.
    Mixed,
}

/// Buffers reused from frame to frame.
#[derive(Default)]
pub(super) struct BlockScratch {
    coarse: Vec<Corner>,
    blocks: Vec<Block>,
    active: Vec<bool>,
    /// Per block: its left and right neighbours are of its class.
    row_alike: Vec<bool>,
    /// The buffers of each thread drawing (one per band of block rows).
    lanes: [Lane; 2],
    /// Render every block per pixel, over the whole image (a reference for tests).
    pub exhaustive: bool,
    /// Draw the lower half of the block rows on a second thread (the same
    /// pixels: every pixel is computed by the same operations either way).
    pub two_threads: bool,
}

impl BlockScratch {
    /// Empty buffers, drawing on two threads or one.
    pub(super) fn with_threads(two_threads: bool) -> BlockScratch {
        BlockScratch { two_threads, ..BlockScratch::default() }
    }
}

/// The buffers of one thread drawing a band of block rows.
#[derive(Default)]
struct Lane {
    patch: Vec<f32>,
    corners: Vec<Corner>,
    horizontal: Vec<f32>,
    vertical: Vec<f32>,
    fixed: Vec<i16>,
}

/// Fewest block rows worth a second thread (handing a band to it costs
/// about as much as drawing a few rows of blocks).
const MIN_ROWS_TWO_THREADS: usize = 8;

/// The block grid of one frame and what is known of each block, shared by
/// the threads drawing it.
struct Grid<'a> {
    rect: PixelRect,
    block_size: usize,
    nbx: usize,
    nby: usize,
    blocks: &'a [Block],
    active: &'a [bool],
}

impl Grid<'_> {
    fn block_rect(&self, bx: usize, by: usize) -> PixelRect {
        let (w, h, b, rect) = (self.rect.width(), self.rect.height(), self.block_size, self.rect);
        PixelRect {
            x0: rect.x0 + (bx * b).min(w),
            y0: rect.y0 + (by * b).min(h),
            x1: rect.x0 + ((bx + 1) * b).min(w),
            y1: rect.y0 + ((by + 1) * b).min(h),
        }
    }
}

/// Plane coordinates (m; NaN when the ray misses) and part at a pixel corner.
#[derive(Clone, Copy)]
struct Corner {
    ab: [f64; 2],
    part: u32,
}

/// The pattern with its parts' colours resolved for `C` channels.
struct Resolved<'a, P, const C: usize> {
    pattern: &'a P,
    /// Colour class of each part: 0 = background, else an index in `classes`.
    part_class: Vec<u16>,
    classes: Vec<[f32; C]>,
    holes: Vec<Option<[f64; 4]>>,
}

impl<'a, P: PlanarPattern, const C: usize> Resolved<'a, P, C> {
    fn new(pattern: &'a P) -> Self {
        let mut classes: Vec<[f32; C]> = vec![[0.0; C]];
        let mut part_class = Vec::new();
        for part in 0..pattern.part_count() {
            let class = match pattern.colour(part) {
                None => 0,
                Some(rgb) => {
                    let colour: [f32; C] = std::array::from_fn(|c| if C == 1 { luma(rgb) } else { rgb[c] });
                    match classes.iter().position(|k| *k == colour) {
                        Some(k) if k > 0 => k,
                        _ => {
                            classes.push(colour);
                            classes.len() - 1
                        }
                    }
                }
            };
            part_class.push(class as u16);
        }
        let holes = (0..pattern.part_count()).map(|part| pattern.hole(part)).collect();
        Resolved { pattern, part_class, classes, holes }
    }

    #[inline]
    fn class(&self, part: u32) -> u16 {
        if part == MISS { 0 } else { self.part_class[part as usize] }
    }

    /// The colour class of the quadrilateral of these corners, if it has one.
    #[inline]
    fn uniform_class(&self, corners: [Corner; 4]) -> Option<u16> {
        let part = corners[0].part;
        let same_part = corners.iter().all(|c| c.part == part);
        if part == MISS || corners.iter().any(|c| c.part == MISS) {
            return same_part.then_some(0);
        }
        let (mut a0, mut a1, mut b0, mut b1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for c in corners {
            a0 = a0.min(c.ab[0]);
            a1 = a1.max(c.ab[0]);
            b0 = b0.min(c.ab[1]);
            b1 = b1.max(c.ab[1]);
        }
        // A margin of 1 % of the footprint covers the curvature of its edges.
        let margin = 0.01 * ((a1 - a0) + (b1 - b0));
        let bounds = [a0 - margin, a1 + margin, b0 - margin, b1 + margin];
        if same_part && self.holes[part as usize].is_none_or(|hole| disjoint(bounds, hole)) {
            return Some(self.class(part));
        }
        self.pattern.colour_in_box(bounds).map(|part| self.class(part))
    }
}

/// Draws `pattern` on `plane` into `target` over `rect`, which must contain
/// the plane's outline grown by at least `block_size + kernel radius` pixels
/// (or reach the image border there). `block_size` must be at least the
/// kernel radius. Classifies the blocks, then draws them in one band of
/// block rows or (`scratch.two_threads`) two, on two threads.
pub(super) fn draw_plane<P: PlanarPattern + Sync, const C: usize>(
    scene: &Scene<'_>,
    plane: &PlaneInCamera,
    pattern: &P,
    rect: PixelRect,
    block_size: usize,
    target: &mut Target<'_>,
    scratch: &mut BlockScratch,
) {
    let resolved = Resolved::<P, C>::new(pattern);
    let corner_at = |i: usize, j: usize| -> Corner {
        let [x, y] = scene.map.corner(i, j);
        match plane.hit(x, y) {
            Some((a, b)) => Corner { ab: [a, b], part: pattern.part(a, b) },
            None => Corner { ab: [f64::NAN; 2], part: MISS },
        }
    };
    let (w, h) = (rect.width(), rect.height());
    let (nbx, nby) = (w.div_ceil(block_size), h.div_ceil(block_size));

    // Classify blocks from the parts at their corners.
    scratch.coarse.clear();
    for by in 0..=nby {
        for bx in 0..=nbx {
            let x = rect.x0 + (bx * block_size).min(w);
            let y = rect.y0 + (by * block_size).min(h);
            scratch.coarse.push(corner_at(x, y));
        }
    }
    scratch.blocks.clear();
    for by in 0..nby {
        for bx in 0..nbx {
            let k = by * (nbx + 1) + bx;
            let corners = [k, k + 1, k + nbx + 1, k + nbx + 2].map(|k| scratch.coarse[k]);
            let class = if scratch.exhaustive { None } else { resolved.uniform_class(corners) };
            scratch.blocks.push(class.map_or(Block::Mixed, Block::Uniform));
        }
    }
    mark_active(&scratch.blocks, nbx, &mut scratch.row_alike, &mut scratch.active);

    let grid = Grid { rect, block_size, nbx, nby, blocks: &scratch.blocks, active: &scratch.active };
    let [upper, lower] = &mut scratch.lanes;
    if !scratch.two_threads || nby < MIN_ROWS_TWO_THREADS {
        draw_band::<P, C>(scene, &grid, 0..nby, &corner_at, &resolved, upper, target);
        return;
    }
    // Two bands of block rows, each drawn (and blurred) by its own thread
    // into its own rows of the frame; each renders the block row beyond its
    // edge too, which its blur reads. They split the work, not the rows.
    let split = balanced_split(&grid);
    let split_y = rect.y0 + split * block_size;
    let bytes = (split_y - target.row0) * target.image_width * C;
    let (top, bottom) = std::mem::take(&mut target.data).split_at_mut(bytes);
    let mut top = Target { data: top, ..*target };
    let mut bottom = Target { data: bottom, row0: split_y, ..*target };
    let (grid, corner_at, resolved) = (&grid, &corner_at, &resolved);
    // The second band goes to a pool thread, which waits between frames: a
    // frame starts (and ends) no thread.
    band_pool().in_place_scope(|s| {
        s.spawn(move |_| draw_band::<P, C>(scene, grid, split..nby, corner_at, resolved, lower, &mut bottom));
        draw_band::<P, C>(scene, grid, 0..split, corner_at, resolved, upper, &mut top);
    });
}

/// The pool that draws the second band: one thread of its own. Rayon's
/// global pool has a thread per core, and each of them woken by a frame
/// spins a while (yielding) before it sleeps again: on two busy cores that
/// was a few per cent of a trial's CPU time for no work. A pool that cannot
/// be built leaves the global one.
fn band_pool() -> &'static BandPool {
    static POOL: OnceLock<BandPool> = OnceLock::new();
    POOL.get_or_init(|| {
        match rayon::ThreadPoolBuilder::new().num_threads(1).thread_name(|_| "render-band".into()).build() {
            Ok(pool) => BandPool::Own(pool),
            Err(e) => {
                tracing::warn!(
                    "sim camera: no thread of its own for the second band ({e}); rayon's pool draws it"
                );
                BandPool::Global
            }
        }
    })
}

/// Where the second band is drawn.
enum BandPool {
    Own(rayon::ThreadPool),
    Global,
}

impl BandPool {
    fn in_place_scope<'scope>(&self, op: impl FnOnce(&rayon::Scope<'scope>)) {
        match self {
            BandPool::Own(pool) => pool.in_place_scope(op),
            BandPool::Global => rayon::in_place_scope(op),
        }
    }
}

/// Marks the active blocks of a grid `nbx` blocks wide: mixed, or next to
/// (one of the 8 around) a block of another class; outside the grid is
/// background. Each block is compared with its row neighbours once
/// (`row_alike`), then with the rows above and below through those.
fn mark_active(blocks: &[Block], nbx: usize, row_alike: &mut Vec<bool>, active: &mut Vec<bool>) {
    const OUTSIDE: Block = Block::Uniform(0);
    row_alike.clear();
    for row in blocks.chunks_exact(nbx) {
        for (bx, &me) in row.iter().enumerate() {
            let left = if bx == 0 { OUTSIDE } else { row[bx - 1] };
            let right = row.get(bx + 1).copied().unwrap_or(OUTSIDE);
            row_alike.push(left == me && right == me);
        }
    }
    let nby = blocks.len() / nbx;
    active.clear();
    for by in 0..nby {
        for bx in 0..nbx {
            let me = blocks[by * nbx + bx];
            // Row `y` (none: outside the grid) holds three blocks equal to this one.
            let alike = |y: Option<usize>| match y {
                None => me == OUTSIDE,
                Some(y) => row_alike[y * nbx + bx] && blocks[y * nbx + bx] == me,
            };
            let below = (by + 1 < nby).then_some(by + 1);
            let calm = me != Block::Mixed && alike(Some(by)) && alike(by.checked_sub(1)) && alike(below);
            active.push(!calm);
        }
    }
}

/// The first block row of the second band: where the rows before it hold
/// half of the blocks drawn per pixel (active blocks, mixed ones counted
/// twice: they are rendered sample by sample too), at least one row in
/// each band. The marker's edges make some rows far busier than others, so
/// half the rows can be well over half the work.
fn balanced_split(grid: &Grid<'_>) -> usize {
    let weight = |by: usize| -> usize {
        (0..grid.nbx)
            .map(|bx| {
                let k = by * grid.nbx + bx;
                usize::from(grid.active[k]) + usize::from(grid.blocks[k] == Block::Mixed)
            })
            .sum()
    };
    let total: usize = (0..grid.nby).map(weight).sum();
    let mut before = 0;
    for by in 0..grid.nby - 1 {
        before += weight(by);
        if 2 * before >= total {
            return (by + 1).max(1);
        }
    }
    grid.nby - 1
}

/// Renders, blurs and writes the block rows `rows` of `grid`, with `lane`'s buffers.
fn draw_band<P: PlanarPattern + Sync, const C: usize>(
    scene: &Scene<'_>,
    grid: &Grid<'_>,
    rows: std::ops::Range<usize>,
    corner_at: &impl Fn(usize, usize) -> Corner,
    resolved: &Resolved<'_, P, C>,
    lane: &mut Lane,
    target: &mut Target<'_>,
) {
    let (rect, nbx, nby) = (grid.rect, grid.nbx, grid.nby);
    // Render what the blur of active blocks reads: active blocks and their
    // neighbours, in the band and the block row on either side of it.
    lane.patch.resize(rect.width() * rect.height() * C, 0.0);
    for by in rows.start.saturating_sub(1)..(rows.end + 1).min(nby) {
        for bx in 0..nbx {
            let near_active = (by.saturating_sub(1)..(by + 2).min(nby))
                .any(|y| (bx.saturating_sub(1)..(bx + 2).min(nbx)).any(|x| grid.active[y * nbx + x]));
            if near_active {
                let block = grid.block_rect(bx, by);
                match grid.blocks[by * nbx + bx] {
                    Block::Uniform(class) => fill_block(scene, rect, block, class, resolved, lane),
                    Block::Mixed => render_block(scene, rect, block, corner_at, resolved, lane),
                }
            }
        }
    }

    // Write: runs of active blocks blurred, calm coloured blocks as constants;
    // calm background is already in the frame.
    for by in rows {
        let mut bx = 0;
        while bx < nbx {
            let start = bx;
            if grid.active[by * nbx + bx] {
                while bx < nbx && grid.active[by * nbx + bx] {
                    bx += 1;
                }
                let run = PixelRect { x1: grid.block_rect(bx - 1, by).x1, ..grid.block_rect(start, by) };
                blur_span::<C>(scene.kernel, rect, run, lane, target);
            } else {
                let me = grid.blocks[by * nbx + bx];
                while bx < nbx && !grid.active[by * nbx + bx] && grid.blocks[by * nbx + bx] == me {
                    bx += 1;
                }
                if let Block::Uniform(class @ 1..) = me {
                    let run = PixelRect { x1: grid.block_rect(bx - 1, by).x1, ..grid.block_rect(start, by) };
                    write_constant(run, resolved.classes[class as usize], &mut lane.fixed, target);
                }
            }
        }
    }
}

/// Fills a uniform block of the patch with its colour or the background.
fn fill_block<P: PlanarPattern, const C: usize>(
    scene: &Scene<'_>,
    rect: PixelRect,
    block: PixelRect,
    class: u16,
    resolved: &Resolved<'_, P, C>,
    lane: &mut Lane,
) {
    let row_len = block.width() * C;
    for v in block.y0..block.y1 {
        let dst_start = ((v - rect.y0) * rect.width() + (block.x0 - rect.x0)) * C;
        let dst = &mut lane.patch[dst_start..dst_start + row_len];
        if class == 0 {
            let src_start = (v * scene.map.width() + block.x0) * C;
            dst.copy_from_slice(&scene.background[src_start..src_start + row_len]);
        } else {
            let colour = &resolved.classes[class as usize];
            dst.chunks_exact_mut(C).for_each(|px| px.copy_from_slice(colour));
        }
    }
}

/// Renders a mixed block pixel by pixel: exact plane coordinates at the pixel
/// corners, the [`SAMPLES`] where a pixel is not uniform,
/// their plane coordinates interpolated bilinearly between its corners (the
/// pixel-to-plane map is smooth, so the error is far below a sample spacing).
fn render_block<P: PlanarPattern, const C: usize>(
    scene: &Scene<'_>,
    rect: PixelRect,
    block: PixelRect,
    corner_at: &impl Fn(usize, usize) -> Corner,
    resolved: &Resolved<'_, P, C>,
    lane: &mut Lane,
) {
    let stride = block.width() + 1;
    lane.corners.clear();
    for j in block.y0..=block.y1 {
        for i in block.x0..=block.x1 {
            lane.corners.push(corner_at(i, j));
        }
    }
    let inv_samples = 1.0 / SAMPLES.len() as f32;
    let image_width = scene.map.width();
    for v in block.y0..block.y1 {
        let jj = v - block.y0;
        let row_start = ((v - rect.y0) * rect.width() + (block.x0 - rect.x0)) * C;
        let bg_start = (v * image_width + block.x0) * C;
        for ii in 0..block.width() {
            let k = jj * stride + ii;
            let corners = [k, k + 1, k + stride, k + stride + 1].map(|k| lane.corners[k]);
            let bg: [f32; C] = std::array::from_fn(|c| scene.background[bg_start + ii * C + c]);
            let dst = &mut lane.patch[row_start + ii * C..row_start + (ii + 1) * C];
            if let Some(class) = resolved.uniform_class(corners) {
                dst.copy_from_slice(if class == 0 { &bg } else { &resolved.classes[class as usize] });
                continue;
            }
            let [c00, c10, c01, c11] = corners.map(|c| c.ab);
            let mut sum = [0.0f32; C];
            for &(fu, fv) in &SAMPLES {
                let left = [c00[0] + (c01[0] - c00[0]) * fv, c00[1] + (c01[1] - c00[1]) * fv];
                let right = [c10[0] + (c11[0] - c10[0]) * fv, c10[1] + (c11[1] - c10[1]) * fv];
                let (a, b) = (left[0] + (right[0] - left[0]) * fu, left[1] + (right[1] - left[1]) * fu);
                // A corner that missed the plane gives NaN: the sample shows the background.
                let class =
                    if a.is_nan() || b.is_nan() { 0 } else { resolved.class(resolved.pattern.part(a, b)) };
                let colour = if class == 0 { &bg } else { &resolved.classes[class as usize] };
                sum.iter_mut().zip(colour).for_each(|(s, c)| *s += c);
            }
            dst.iter_mut().zip(sum).for_each(|(d, s)| *d = s * inv_samples);
        }
    }
}

/// Blurs a horizontal run of blocks of the patch (reading up to the kernel
/// radius around it, clamped to `rect`) and writes it, noisy and quantised,
/// into the frame.
fn blur_span<const C: usize>(
    kernel: &[f32],
    rect: PixelRect,
    span: PixelRect,
    lane: &mut Lane,
    target: &mut Target<'_>,
) {
    let r = kernel.len() / 2;
    let (w, h) = (rect.width(), rect.height());
    let (x0, x1) = (span.x0 - rect.x0, span.x1 - rect.x0);
    let (y0, y1) = (span.y0 - rect.y0, span.y1 - rect.y0);
    let row_len = (x1 - x0) * C;
    // Horizontal pass over the span's columns, for its rows and r rows around.
    // The first tap sets each sum (as 0 + k x would: the values are not
    // negative), so the buffers need no zeroing.
    let (hy0, hy1) = (y0.saturating_sub(r), (y1 + r).min(h));
    let need = (hy1 - hy0) * row_len;
    if lane.horizontal.len() < need {
        lane.horizontal.resize(need, 0.0);
    }
    for y in hy0..hy1 {
        let row = &lane.patch[y * w * C..(y + 1) * w * C];
        let out = &mut lane.horizontal[(y - hy0) * row_len..(y - hy0 + 1) * row_len];
        if x0 >= r && x1 + r <= w {
            // Interior: one multiply-add per tap over the whole row of the span.
            for (t, &k) in kernel.iter().enumerate() {
                let src = &row[(x0 + t - r) * C..(x1 + t - r) * C];
                add_tap(out, src, k, t == 0);
            }
        } else {
            for (t, &k) in kernel.iter().enumerate() {
                for (x, o) in (x0..x1).zip(out.chunks_exact_mut(C)) {
                    let xs = (x + t).saturating_sub(r).min(w - 1);
                    let src = &row[xs * C..(xs + 1) * C];
                    add_tap(o, src, k, t == 0);
                }
            }
        }
    }
    // Vertical pass, then fixed point, noise and quantisation into the frame.
    lane.fixed.resize(row_len, 0);
    lane.vertical.resize(row_len, 0.0);
    for y in y0..y1 {
        let acc = &mut lane.vertical;
        for (t, &k) in kernel.iter().enumerate() {
            let ys = (y + t).saturating_sub(r).clamp(hy0, hy1 - 1) - hy0;
            let src = &lane.horizontal[ys * row_len..(ys + 1) * row_len];
            add_tap(acc, src, k, t == 0);
        }
        lane.fixed.iter_mut().zip(acc.iter()).for_each(|(f, &v)| *f = to_fixed(v));
        target.write(rect.x0 + x0, rect.y0 + y, C, &lane.fixed);
    }
}

/// Writes a block of one colour, noisy and quantised, into the frame.
fn write_constant<const C: usize>(
    block: PixelRect,
    colour: [f32; C],
    fixed: &mut Vec<i16>,
    target: &mut Target<'_>,
) {
    let row_len = block.width() * C;
    fixed.clear();
    for _ in 0..block.width() {
        fixed.extend(colour.iter().map(|&v| to_fixed(v)));
    }
    debug_assert_eq!(fixed.len(), row_len);
    for y in block.y0..block.y1 {
        target.write(block.x0, y, C, fixed);
    }
}

/// One tap of the blur: `sums += k * src`, or `sums = k * src` for the
/// first tap (the same bits as adding it to zeros: the values are not
/// negative), so that the sums need no zeroing.
#[inline]
fn add_tap(sums: &mut [f32], src: &[f32], k: f32, first: bool) {
    if first {
        sums.iter_mut().zip(src).for_each(|(o, s)| *o = k * s);
    } else {
        sums.iter_mut().zip(src).for_each(|(o, s)| *o += k * s);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid<'a>(nby: usize, blocks: &'a [Block], active: &'a [bool]) -> Grid<'a> {
        let nbx = blocks.len() / nby;
        let rect = PixelRect { x0: 0, y0: 0, x1: 4 * nbx, y1: 4 * nby };
        Grid { rect, block_size: 4, nbx, nby, blocks, active }
    }

    /// Catches a neighbour missed or out of the grid at any border (a
    /// block left calm beside another class would be written as a
    /// constant, unblurred): the marking against comparing all 9 blocks
    /// around each, on grids of random classes from 1x1 to 7x6.
    #[test]
    fn active_blocks_are_those_next_to_another_class() {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = |n: u64| {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            (state >> 33) % n
        };
        let (mut row_alike, mut active) = (Vec::new(), Vec::new());
        for _ in 0..400 {
            let (nbx, nby) = (1 + next(7) as usize, 1 + next(6) as usize);
            let blocks: Vec<Block> = (0..nbx * nby)
                .map(|_| match next(4) {
                    0 => Block::Mixed,
                    1 => Block::Uniform(1),
                    _ => Block::Uniform(0),
                })
                .collect();
            mark_active(&blocks, nbx, &mut row_alike, &mut active);
            let at = |x: isize, y: isize| {
                if x < 0 || y < 0 || x >= nbx as isize || y >= nby as isize {
                    Block::Uniform(0)
                } else {
                    blocks[y as usize * nbx + x as usize]
                }
            };
            for by in 0..nby as isize {
                for bx in 0..nbx as isize {
                    let me = at(bx, by);
                    let calm = me != Block::Mixed
                        && (-1..=1).all(|dy| (-1..=1).all(|dx| at(bx + dx, by + dy) == me));
                    assert_eq!(
                        active[by as usize * nbx + bx as usize],
                        !calm,
                        "{nbx}x{nby} block ({bx}, {by})"
                    );
                }
            }
        }
    }

    /// The split follows the work: with all of it in the first rows the
    /// second band starts right after them (half the rows would leave the
    /// first thread all of it); with none, or all in the last row, each
    /// band still gets a row.
    #[test]
    fn the_bands_split_the_blocks_drawn_per_pixel_not_the_rows() {
        let (nbx, nby) = (5, 10);
        let mut blocks = vec![Block::Uniform(0); nbx * nby];
        let mut active = vec![false; nbx * nby];
        for k in 0..3 * nbx {
            active[k] = true;
            blocks[k] = Block::Mixed;
        }
        // Rows 0-2 hold all the work: half of it is done after row 1 (of 1.5 rows).
        assert_eq!(balanced_split(&grid(nby, &blocks, &active)), 2);
        let idle = vec![false; nbx * nby];
        let uniform = vec![Block::Uniform(1); nbx * nby];
        assert_eq!(balanced_split(&grid(nby, &uniform, &idle)), 1);
        let mut last = idle.clone();
        last[(nby - 1) * nbx] = true;
        assert_eq!(balanced_split(&grid(nby, &uniform, &last)), nby - 1);
    }
}
