// Binning: which tiles each projected Gaussian reaches, and the (tile, index) pairs in depth order
// that the tile sort turns into per-tile lists. project_kernel projects (project.cu's
// project_one) and counts each Gaussian's tiles; depth_keys and gather_counts feed the depth sort
// and the scan of the counts (sort.rs); emit_keys writes the pairs; tile_ranges finds each tile's
// run after the sort. A Gaussian's tiles are those its alpha >= 1/255 ellipse reaches (row_span),
// not its whole bounding box: fewer pairs to sort, stage and test, and the same image.

// Padding of row_span's band and columns: 0.1 px, and 2e-3 of the extent for the rounding of the
// square root where the ellipse's edge runs along a row (near its top and bottom).
#define SPAN_PAD 0.1f
#define SPAN_REL 2e-3f

// Half the chord of the ellipse d^T K d = level at row offset dy, times a: sqrt(a level - k dy^2)
// with k = det K (0 past the ellipse's top and bottom). The square root and the divisions in
// row_span are the hardware's approximate ones (a few ulp, far inside the padding; each the same
// instruction in both kernels, so as deterministic as the rounded ones, and several times cheaper).
__device__ __forceinline__ float chord(float a, float k, float level, float dy) {
    float disc = __fsub_rn(__fmul_rn(a, level), __fmul_rn(k, __fmul_rn(dy, dy)));
    return disc > 0.0f ? __fmul_rn(disc, rsqrtf(disc)) : 0.0f;
}

// The tile columns [c0, c1] of tile row `ty` that Gaussian p's alpha >= 1/255 ellipse reaches,
// within its box's columns [x0, x1] (none when c1 < c0): the x range of the ellipse over the
// row's band of y (padded), which is the ellipse's leftmost (rightmost) x where the band holds
// the point that reaches it, else the nearer band edge's. A superset of the tiles where
// alpha_at accepts a pixel centre: the box's other tiles hold none (the saving: 18 % of the
// pairs at 100k random Gaussians and 1920x1080, more for long thin ones). project_kernel counts
// with it and emit_keys walks it, so both must compute the same bits: explicit intrinsics only
// (no contraction into FMAs that could differ between the two kernels).
__device__ __forceinline__ void row_span(const Proj& p, int ty, int x0, int x1, int& c0, int& c1) {
    float a = p.conic[0], b = p.conic[1], c = p.conic[2];
    float level = -2.0f * p.power_min, ex = p.extent[0], ey = p.extent[1];
    float k = __fsub_rn(__fmul_rn(a, c), __fmul_rn(b, b));
    float ya = fmaxf(__fsub_rn((float)(ty * TILE), p.mean[1]) - SPAN_PAD, -ey);
    float yb = fminf(__fsub_rn((float)((ty + 1) * TILE), p.mean[1]) + SPAN_PAD, ey);
    if (!(ya <= yb) || !(k > 0.0f) || !(a > 0.0f)) {  // degenerate: the box's columns
        c0 = x0; c1 = x1;
        return;
    }
    // x = (-b dy -+ chord) / a at the band's edges; the extreme x is reached at dy = +-b ex / c.
    float ra = chord(a, k, level, ya), rb = chord(a, k, level, yb);
    float ba = __fmul_rn(b, ya), bb = __fmul_rn(b, yb);
    float dy_left = __fdividef(__fmul_rn(b, ex), c);
    float lo = (dy_left >= ya && dy_left <= yb) ? -ex : __fdividef(fminf(-ba - ra, -bb - rb), a);
    float hi = (-dy_left >= ya && -dy_left <= yb) ? ex : __fdividef(fmaxf(-ba + ra, -bb + rb), a);
    float pad = __fmaf_rn(SPAN_REL, ex, SPAN_PAD);
    const float inv_tile = 1.0f / (float)TILE;  // a power of two: exact
    c0 = max((int)floorf(__fmul_rn(__fsub_rn(__fadd_rn(p.mean[0], lo), pad), inv_tile)), x0);
    c1 = min((int)floorf(__fmul_rn(__fadd_rn(__fadd_rn(p.mean[0], hi), pad), inv_tile)), x1);
}

// Projects every Gaussian and counts the tiles its alpha >= 1/255 ellipse reaches (row_span, row by
// row over the tile rows of the ellipse's box; `rects` keeps the box for emit_keys).
extern "C" __global__ void project_kernel(int n, const float* means, const float* log_scales, const float* rots,
                                          const float* logits, const float* sh, Cam cam, Opts o, Proj* proj,
                                          int* valid, unsigned* counts, int4* rects) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    Proj p;
    Frame f;
    // Staging the block's SH rows in shared memory (as chain_kernel does) made this kernel slower
    // (0.86 -> 0.92 ms at 3M Gaussians, 1920x1080): it is not bound by the SH loads.
    const float* shi = sh + (size_t)i * 3 * (o.sh_degree + 1) * (o.sh_degree + 1);
    bool ok = project_one(i, means, log_scales, rots, logits, shi, cam, o, p, f);
    valid[i] = ok;
    counts[i] = 0;
    if (!ok) return;
    proj[i] = p;
    int x0, x1, y0, y1;
    if (o.smooth) {
        x0 = 0; y0 = 0; x1 = o.tiles_x - 1; y1 = o.tiles_y - 1;
    } else {
        float t = (float)TILE;
        x0 = (int)fmaxf(floorf((p.mean[0] - p.extent[0]) / t), 0.0f);
        x1 = (int)fminf(floorf((p.mean[0] + p.extent[0]) / t), (float)(o.tiles_x - 1));
        y0 = (int)fmaxf(floorf((p.mean[1] - p.extent[1]) / t), 0.0f);
        y1 = (int)fminf(floorf((p.mean[1] + p.extent[1]) / t), (float)(o.tiles_y - 1));
    }
    if (x1 < x0 || y1 < y0) return;
    unsigned count = (unsigned)((x1 - x0 + 1) * (y1 - y0 + 1));
    if (!o.smooth) {
        count = 0;
        for (int ty = y0; ty <= y1; ty++) {
            int c0, c1;
            row_span(p, ty, x0, x1, c0, c1);
            count += (unsigned)max(c1 - c0 + 1, 0);
        }
    }
    counts[i] = count;
    rects[i] = make_int4(x0, y0, x1, y1);
}

// The depth sort's pairs: every Gaussian's depth bits (positive floats order as their bits) and
// its index; those that cover no tile sort last.
extern "C" __global__ void depth_keys(int n, const Proj* proj, const unsigned* counts, unsigned* keys, unsigned* vals) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    keys[i] = counts[i] == 0 ? 0xffffffffu : __float_as_uint(proj[i].depth);
    vals[i] = (unsigned)i;
}

// The tile counts in depth order: out[j] = counts[order[j]].
extern "C" __global__ void gather_counts(int n, const unsigned* order, const unsigned* counts, unsigned* out) {
    int j = blockIdx.x * blockDim.x + threadIdx.x;
    if (j < n) out[j] = counts[order[j]];
}

// The inclusive sum of v over lanes 0..lane of the warp.
__device__ __forceinline__ unsigned warp_scan(unsigned v, int lane) {
    for (int d = 1; d < 32; d <<= 1) {
        unsigned t = __shfl_up_sync(0xffffffffu, v, d);
        if (lane >= d) v += t;
    }
    return v;
}

// The last lane whose `start` is at most s (`start` non-decreasing over the lanes; a lane with
// nothing to write has the next lane's start, so the last such lane always has something).
__device__ __forceinline__ int owner_lane(unsigned start, unsigned s) {
    int g = 0;
    for (int step = 16; step > 0; step >>= 1)
        if (__shfl_sync(0xffffffffu, start, g + step) <= s) g += step;
    return g;
}

// Writes one (tile, index) pair per tile a Gaussian reaches, the Gaussians in depth order
// (`order`, ties by index; `counts` and `offsets` in that order too), so that a stable sort by
// tile leaves each tile's pairs sorted by depth, then index. Each tile row's columns come from
// row_span, as project_kernel counted them (the whole box's rows in smooth mode). Stores are
// coalesced, in two passes over the warp's 32 Gaussians:
// - those whose box spans at most two tile rows (most of them): each lane finds its Gaussian's
//   rows' columns, and the warp writes their slots together, 32 at a time (a slot's Gaussian:
//   the last lane whose run starts at or before it);
// - the taller ones one after another: the lanes find the columns of 32 of its rows at once, a
//   warp scan places each row's run, and the warp writes the runs 32 slots at a time.
// (One slot per lane walking its Gaussian's rows from the top cost 1.67 ms at 3M Gaussians and
// 1920x1080, the taller pass alone for every Gaussian 0.85 ms, against 0.32 ms for the box's
// plain rows.) A Gaussian never writes past its own count of slots.
extern "C" __global__ void emit_keys(int n, const unsigned* order, const unsigned* counts, const unsigned* offsets,
                                     const int4* rects, const Proj* proj, int smooth, int tiles_x, unsigned* keys,
                                     unsigned* vals) {
    int j = blockIdx.x * blockDim.x + threadIdx.x;
    int lane = threadIdx.x & 31;
    unsigned c = j < n ? counts[j] : 0u;
    unsigned o = 0, idx = 0;
    int4 r = make_int4(0, 0, -1, -1);
    if (c > 0) {
        o = offsets[j];
        idx = order[j];
        r = rects[idx];
    }
    bool low = c > 0 && r.w - r.y < 2;
    // Pass 1: the low Gaussians, row r.y's first column and length and row r.y + 1's first column.
    int col0 = r.x, len0 = r.z - r.x + 1, col1 = r.x;
    if (low && !smooth) {
        int c0, c1;
        row_span(proj[idx], r.y, r.x, r.z, c0, c1);
        col0 = c0;
        len0 = max(c1 - c0 + 1, 0);
        if (r.w > r.y) {
            row_span(proj[idx], r.w, r.x, r.z, c0, c1);
            col1 = c0;
        }
    }
    unsigned mine = low ? c : 0u, incl = warp_scan(mine, lane), run = incl - mine;
    unsigned total = __shfl_sync(0xffffffffu, incl, 31);
    for (unsigned v0 = 0; v0 < total; v0 += 32) {
        unsigned v = v0 + lane;
        int g = owner_lane(run, v);
        unsigned local = v - __shfl_sync(0xffffffffu, run, g);
        unsigned og = __shfl_sync(0xffffffffu, o, g), ig = __shfl_sync(0xffffffffu, idx, g);
        int y = __shfl_sync(0xffffffffu, r.y, g), x1 = __shfl_sync(0xffffffffu, r.z, g);
        int a0 = __shfl_sync(0xffffffffu, col0, g), l0 = __shfl_sync(0xffffffffu, len0, g);
        int a1 = __shfl_sync(0xffffffffu, col1, g);
        if (v < total) {
            bool first = (int)local < l0;
            int tx = first ? a0 + (int)local : a1 + ((int)local - l0);
            keys[og + local] = (unsigned)((first ? y : y + 1) * tiles_x + min(tx, x1));
            vals[og + local] = ig;
        }
    }
    // Pass 2: the taller Gaussians, one at a time.
    unsigned todo = __ballot_sync(0xffffffffu, c > 0 && !low);
    while (todo) {
        int g = __ffs(todo) - 1;
        todo &= todo - 1;
        unsigned og = __shfl_sync(0xffffffffu, o, g), cg = __shfl_sync(0xffffffffu, c, g);
        unsigned ig = __shfl_sync(0xffffffffu, idx, g);
        int4 b = make_int4(__shfl_sync(0xffffffffu, r.x, g), __shfl_sync(0xffffffffu, r.y, g),
                           __shfl_sync(0xffffffffu, r.z, g), __shfl_sync(0xffffffffu, r.w, g));
        unsigned at = og, end = og + cg;
        for (int r0 = b.y; r0 <= b.w && at < end; r0 += 32) {
            int ty = r0 + lane, c0 = b.x, c1 = b.x - 1;
            if (ty <= b.w) {
                if (smooth) c1 = b.z;
                else row_span(proj[ig], ty, b.x, b.z, c0, c1);
            }
            unsigned len = (unsigned)max(c1 - c0 + 1, 0), rin = warp_scan(len, lane), rst = rin - len;
            unsigned rows_total = __shfl_sync(0xffffffffu, rin, 31);
            for (unsigned s0 = 0; s0 < rows_total; s0 += 32) {
                unsigned s = s0 + lane;
                int k = owner_lane(rst, s);
                unsigned ek = __shfl_sync(0xffffffffu, rst, k);
                int ck = __shfl_sync(0xffffffffu, c0, k);
                if (s < rows_total && at + s < end) {
                    keys[at + s] = (unsigned)((r0 + k) * tiles_x + ck + (int)(s - ek));
                    vals[at + s] = ig;
                }
            }
            at += rows_total;
        }
    }
}

// Per tile, the [start, end) of its entries in the sorted keys.
extern "C" __global__ void tile_ranges(unsigned m, const unsigned* keys, uint2* ranges) {
    unsigned i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= m) return;
    unsigned t = keys[i];
    if (i == 0 || keys[i - 1] != t) ranges[t].x = i;
    if (i == m - 1 || keys[i + 1] != t) ranges[t].y = i + 1;
}
