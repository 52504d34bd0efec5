// Forward rasterisation (splat::raster, in f32), and the alpha test and warp-block test that the
// backward (raster_back.cu) shares: one 16x16 block per tile, one thread per pixel (placed by
// pixel_of), the tile's depth-sorted Gaussians staged through shared memory in batches of 256.
// The alpha test is splat::tiles::alpha_at's. (Two pixels per thread, as in the backward, made
// the forward slower: 0.60 -> 0.65-0.70 ms at 100k Gaussians and 1920x1080.)

struct Hot {
    float mean[2], conic[3], opacity, power_min, extent[2];
};

// Straight-line code: every term is computed and the tests combined with `&` (no early returns),
// so the compiler predicates instead of branching and reconverging around each test; with
// SMOOTH a template parameter the smooth-mode tests are not in the other kernel at all. The same
// decisions as splat::tiles::alpha_at, NaN included (each test is the negation of a rejection).
template <bool SMOOTH>
__device__ __forceinline__ bool alpha_at(const Hot& h, float qx, float qy, float& alpha, float& e, bool& clamped) {
    float dx = qx - h.mean[0], dy = qy - h.mean[1];
    float power = -0.5f * (h.conic[0] * dx * dx + h.conic[2] * dy * dy) - h.conic[1] * dx * dy;
    // The fast exponential (gsplat builds with --use_fast_math): 2 ulp and power's rounding, within
    // the parity tests' slack of 1e-5 in ln(alpha).
    e = __expf(power);
    float raw = h.opacity * e;
    clamped = !SMOOTH && raw > ALPHA_MAX;
    alpha = clamped ? ALPHA_MAX : raw;
    if (SMOOTH) return !(power > 0.0f);
    return !(fabsf(dx) > h.extent[0]) & !(fabsf(dy) > h.extent[1]) & !(power > 0.0f) & !(power < h.power_min) &
           (alpha >= ALPHA_MIN);
}

__device__ __forceinline__ Hot hot_of(const Proj& p) {
    Hot h;
    h.mean[0] = p.mean[0]; h.mean[1] = p.mean[1];
    h.conic[0] = p.conic[0]; h.conic[1] = p.conic[1]; h.conic[2] = p.conic[2];
    h.opacity = p.opacity; h.power_min = p.power_min;
    h.extent[0] = p.extent[0]; h.extent[1] = p.extent[1];
    return h;
}

#define BATCH 256

// Which of a tile's warp blocks (8 x BH pixels each, two across: as pixel_of and pixel2_of place
// a warp's pixels) the Gaussian can reach, one bit per block, computed once per Gaussian when a
// batch is staged: a warp whose bit is clear skips the Gaussian without testing its pixels.
// Conservative: a block's bit is clear only where no pixel centre in it passes alpha_at's extent
// test (0.01 px to spare for the rounding of qx - mean). A test against the ellipse as well cost
// more when staging than it saved (BENCHMARKS, issue 30).
template <int BLOCKS, int BH>
__device__ __forceinline__ unsigned warp_blocks(const Proj& p, int tx0, int ty0, int smooth) {
    if (smooth) return (1u << BLOCKS) - 1u;
    const float slack = 0.01f;
    float lx = p.mean[0] - p.extent[0] - slack, hx = p.mean[0] + p.extent[0] + slack;
    float ly = p.mean[1] - p.extent[1] - slack, hy = p.mean[1] + p.extent[1] + slack;
    unsigned m = 0;
#pragma unroll
    for (int w = 0; w < BLOCKS; w++) {
        float x0 = (float)(tx0 + (w & 1) * 8) + 0.5f, y0 = (float)(ty0 + (w >> 1) * BH) + 0.5f;
        if (fmaxf(x0, lx) <= fminf(x0 + 7.0f, hx) && fmaxf(y0, ly) <= fminf(y0 + (float)(BH - 1), hy)) m |= 1u << w;
    }
    return m;
}

// A warp's 32 pixels are an 8x4 block of the 16x16 tile, not two rows of 16: a small Gaussian
// reaches fewer warps, so fewer warps test it and fewer sum its gradients (the backward 7 % faster
// at 100k Gaussians and 1920x1080 on an H100; each pixel's result is the same either way).
__device__ __forceinline__ void pixel_of(int tid, int& x, int& y) {
    int lane = tid & 31, warp = tid >> 5;
    x = (lane & 7) | ((warp & 1) << 3);
    y = (lane >> 3) | ((warp >> 1) << 2);
}

#define FORWARD_PARAMS                                                                                      \
    int width, int height, Opts o, const uint2 *ranges, const unsigned *vals, const Proj *proj, const float *feats, \
        float *out_rgb, float *out_alpha, float *out_depth, float *out_normal, float *out_feat, float *final_t,     \
        unsigned *last
#define FORWARD_ARGS \
    width, height, o, ranges, vals, proj, feats, out_rgb, out_alpha, out_depth, out_normal, out_feat, final_t, last

// One tile's forward pass; the kernel below picks SMOOTH from `o` and owns the shared memory.
template <bool SMOOTH>
__device__ __forceinline__ void forward_tile(FORWARD_PARAMS, Proj* sp, unsigned* sid, unsigned char* smask) {
    int tile = blockIdx.y * gridDim.x + blockIdx.x;
    int tid = threadIdx.y * TILE + threadIdx.x;
    int lx, ly;
    pixel_of(tid, lx, ly);
    int px = blockIdx.x * TILE + lx, py = blockIdx.y * TILE + ly;
    bool inside = px < width && py < height;
    float qx = (float)px + 0.5f, qy = (float)py + 0.5f;
    uint2 range = ranges[tile];
    unsigned wbit = 1u << (tid >> 5);
    bool done = !inside;
    float T = 1.0f, rgb[3] = {0.0f, 0.0f, 0.0f}, depth = 0.0f, nrm[3] = {0.0f, 0.0f, 0.0f};
    float fsum[NF > 0 ? NF : 1];
    for (int c = 0; c < NF; c++) fsum[c] = 0.0f;
    unsigned my_last = 0;
    for (unsigned start = range.x; start < range.y; start += BATCH) {
        if (__syncthreads_count(done) == BATCH) break;
        unsigned k = start + tid;
        if (k < range.y) {
            unsigned id = vals[k];
            sid[tid] = id;
            Proj p = proj[id];
            sp[tid] = p;
            smask[tid] = (unsigned char)warp_blocks<8, 4>(p, blockIdx.x * TILE, blockIdx.y * TILE, SMOOTH);
        }
        __syncthreads();
        unsigned cnt = min((unsigned)BATCH, range.y - start);
        for (unsigned j = 0; j < cnt && !done; j++) {
            if (!(smask[j] & wbit)) continue;
            const Proj& g = sp[j];
            float alpha, e;
            bool cl;
            if (!alpha_at<SMOOTH>(hot_of(g), qx, qy, alpha, e, cl)) continue;
            float next = T * (1.0f - alpha);
            if (!SMOOTH && next < T_MIN) {
                done = true;
                break;
            }
            float w = alpha * T;
            for (int c = 0; c < 3; c++) {
                rgb[c] += w * fmaxf(g.color[c], 0.0f);
                nrm[c] += w * g.normal[c];
            }
            depth += w * g.depth;
            for (int c = 0; c < NF; c++) fsum[c] += w * feats[(size_t)sid[j] * NF + c];
            T = next;
            my_last = start - range.x + j + 1;
        }
    }
    if (!inside) return;
    int pix = py * width + px;
    for (int c = 0; c < 3; c++) {
        out_rgb[3 * pix + c] = rgb[c] + T * o.bg[c];
        out_normal[3 * pix + c] = nrm[c];
    }
    out_alpha[pix] = 1.0f - T;
    out_depth[pix] = depth;
    for (int c = 0; c < NF; c++) out_feat[(size_t)pix * NF + c] = fsum[c];
    final_t[pix] = T;
    last[pix] = my_last;
}

extern "C" __global__ void __launch_bounds__(256) raster_forward(FORWARD_PARAMS) {
    __shared__ Proj sp[BATCH];
    __shared__ unsigned sid[BATCH];
    __shared__ unsigned char smask[BATCH];
    if (o.smooth) forward_tile<true>(FORWARD_ARGS, sp, sid, smask);
    else forward_tile<false>(FORWARD_ARGS, sp, sid, smask);
}
