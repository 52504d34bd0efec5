// The backward rasterisation (splat::raster_backward, in f32): per tile, back to front, each
// Gaussian's screen-space gradients summed over a warp and added to global memory with integer
// atomics in fixed point (fixed.cu: the same sums whatever order the warps arrive in).
// Two pixels per thread: a block of 128 threads covers the 16x16 tile, a warp's 32 lanes an 8x8
// block of it (lane pixels at rows r and r + 4), so each Gaussian's shared-memory read, block
// test, ballot and warp sum serve 64 pixels rather than 32 (fwd+bwd at 100k Gaussians and
// 1920x1080 on an H100: 2.78 -> 2.67 ms with the warp-block test, BENCHMARKS, issue 30).

// The backward's per-Gaussian sums over a warp. Reducing each of the G2N values alone took 5
// shuffles apiece (65) and lane 0 then issued G2N atomics one after another. Recursive halving
// instead: each round a lane keeps half of its values and sends the other half to the lane `o`
// away, which sends back the matching half, so the values left halve while the lanes holding
// each value's partial sum double; 5 rounds take 16 shuffles for 16 values (31 for 32). Lane l
// then holds the warp's whole sum of value red_index(l) (the same pairing as a tree of
// shfl_down, so the same sum bit for bit), and the G2N atomics go out together, one per lane.
// Where at most SPARSE_HITS lanes hit the Gaussian, those lanes add their own values instead
// (a few atomics cost less than the 16 shuffles).
#define SPARSE_HITS 2
#define RED_P (G2N <= 16 ? 16 : 32)

template <int H>
__device__ __forceinline__ void halve(float* v, bool up, int o) {
#pragma unroll
    for (int i = 0; i < H; i++) {
        float keep = up ? v[i + H] : v[i], send = up ? v[i] : v[i + H];
        v[i] = keep + __shfl_xor_sync(0xffffffffu, send, o);
    }
}

// Leaves in v[0] the warp's sum of value red_index(lane) of v[0..RED_P).
__device__ __forceinline__ void spread_sum(float* v, int lane) {
    halve<RED_P / 2>(v, lane & 16, 16);
    halve<RED_P / 4>(v, lane & 8, 8);
    halve<RED_P / 8>(v, lane & 4, 4);
    halve<RED_P / 16>(v, lane & 2, 2);
    if (RED_P == 32) halve<1>(v, lane & 1, 1);
    else v[0] += __shfl_xor_sync(0xffffffffu, v[0], 1);
}

// The colour-only sums (no feature channels, and no lane of the warp with a depth or normal
// gradient: only values 0..8 can be non-zero): values 0..7 by three halving rounds (lane l then
// holds value l >> 2 summed over 8 lanes) and two plain rounds, value 8 by a butterfly. 14
// shuffles and 14 selects rather than spread_sum's 16 and 30 (the backward 1.55 -> 1.51 ms at
// 100k Gaussians and 1920x1080). Leaves the sum of value lane >> 2 in v[0] (lanes 4k hold value
// k), and value 8's in every lane's v[8].
__device__ __forceinline__ void lean_sum(float* v, int lane) {
    float v8 = v[8];
#pragma unroll
    for (int o = 16; o >= 1; o >>= 1) v8 += __shfl_xor_sync(0xffffffffu, v8, o);
    halve<4>(v, lane & 16, 16);
    halve<2>(v, lane & 8, 8);
    halve<1>(v, lane & 4, 4);
    v[0] += __shfl_xor_sync(0xffffffffu, v[0], 2);
    v[0] += __shfl_xor_sync(0xffffffffu, v[0], 1);
    v[8] = v8;
}

// Which value's sum lane `lane` holds after spread_sum, and whether it adds it (one lane of each
// pair when RED_P is 16).
__device__ __forceinline__ int red_index(int lane) { return RED_P == 32 ? lane : lane >> 1; }
__device__ __forceinline__ bool red_owner(int lane) { return RED_P == 32 || (lane & 1) == 0; }

#define BWD_THREADS 128

// The pixels of thread `tid` (k = 0, 1) in its tile.
__device__ __forceinline__ void pixel2_of(int tid, int k, int& x, int& y) {
    int lane = tid & 31, warp = tid >> 5;
    x = (lane & 7) | ((warp & 1) << 3);
    y = (lane >> 3) | (k << 2) | ((warp >> 1) << 3);
}

// One pixel's running state in the backward: its upstream gradients and what lies behind the
// current Gaussian (colour, normal, depth and features composited so far from the back).
struct Px {
    float qx, qy, T, t_final, u_rgb[3], u_n[3], u_a, u_d, b_rgb[3], b_n[3], b_d;
    float u_f[NF > 0 ? NF : 1], s_f[NF > 0 ? NF : 1];
    unsigned last;
};

// Adds pixel `p`'s gradients for the Gaussian `g` it hits (alpha, e, clamped from alpha_at) to
// v[0..G2N) in the G2 row's layout, and steps the pixel's state past the Gaussian.
__device__ __forceinline__ void hit_grads(Px& p, const Proj& g, float alpha, float e, bool cl, const float* fi,
                                          bool geo, float* v) {
    float inv = __fdividef(1.0f, 1.0f - alpha);  // 1 - alpha is in [0.01, 1]: no IEEE slow path needed
    float ti = p.T * inv;
    float w = alpha * ti;
    float vc[3];
#pragma unroll
    for (int c = 0; c < 3; c++) {
        vc[c] = fmaxf(g.color[c], 0.0f);
        if (g.color[c] > 0.0f) v[6 + c] += p.u_rgb[c] * w;
    }
    float d_alpha = p.u_a * p.t_final * inv;
#pragma unroll
    for (int c = 0; c < 3; c++) d_alpha += p.u_rgb[c] * (ti * vc[c] - p.b_rgb[c] * inv);
    if (geo) {
        v[9] += p.u_d * w;
        d_alpha += p.u_d * (ti * g.depth - p.b_d * inv);
#pragma unroll
        for (int c = 0; c < 3; c++) {
            v[10 + c] += p.u_n[c] * w;
            d_alpha += p.u_n[c] * (ti * g.normal[c] - p.b_n[c] * inv);
            p.b_n[c] += w * g.normal[c];
        }
        p.b_d += w * g.depth;
    }
    for (int c = 0; c < NF; c++) {
        v[13 + c] += p.u_f[c] * w;
        d_alpha += p.u_f[c] * (ti * fi[c] - p.s_f[c] * inv);
        p.s_f[c] += w * fi[c];
    }
#pragma unroll
    for (int c = 0; c < 3; c++) p.b_rgb[c] += w * vc[c];
    if (!cl) {
        v[5] += d_alpha * e;
        float dp = d_alpha * alpha;
        float dx = p.qx - g.mean[0], dy = p.qy - g.mean[1];
        v[2] += dp * -0.5f * dx * dx;
        v[3] += dp * -dx * dy;
        v[4] += dp * -0.5f * dy * dy;
        v[0] += dp * (g.conic[0] * dx + g.conic[1] * dy);
        v[1] += dp * (g.conic[1] * dx + g.conic[2] * dy);
    }
    p.T = ti;
}

#define BACKWARD_PARAMS                                                                                     \
    int width, int height, Opts o, const uint2 *ranges, const unsigned *vals, const Proj *proj, const float *feats, \
        const float *final_t, const unsigned *last, const float *up_rgb, const float *up_alpha,                     \
        const float *up_depth, const float *up_normal, const float *up_feat, unsigned long long *g2q,            \
        unsigned *fix_max
#define BACKWARD_ARGS \
    width, height, o, ranges, vals, proj, feats, final_t, last, up_rgb, up_alpha, up_depth, up_normal, up_feat, g2q, fix_max

// One tile's backward pass; the kernel below picks SMOOTH from `o` and owns the shared memory.
template <bool SMOOTH>
__device__ __forceinline__ void backward_tile(BACKWARD_PARAMS, Proj* sp, unsigned* sid, unsigned char* smask,
                                              unsigned& max_last) {
    int tile = blockIdx.y * gridDim.x + blockIdx.x;
    int tid = threadIdx.y * TILE + threadIdx.x;
    int lane = tid & 31;
    uint2 range = ranges[tile];
    float scale = fix_scale(*fix_max);  // upstream_max ran before this kernel
    Px px[2];
    bool any_geo = false;
    unsigned my_last = 0;
#pragma unroll
    for (int k = 0; k < 2; k++) {
        Px& p = px[k];
        int lx, ly;
        pixel2_of(tid, k, lx, ly);
        int x = blockIdx.x * TILE + lx, y = blockIdx.y * TILE + ly;
        p.qx = (float)x + 0.5f;
        p.qy = (float)y + 0.5f;
        p.T = p.t_final = 1.0f;
        p.last = 0;
        p.u_a = p.u_d = p.b_d = 0.0f;
        for (int c = 0; c < 3; c++) p.u_rgb[c] = p.u_n[c] = p.b_n[c] = 0.0f;
        for (int c = 0; c < NF; c++) p.u_f[c] = p.s_f[c] = 0.0f;
        if (x < width && y < height) {
            int pix = y * width + x;
            p.T = p.t_final = final_t[pix];
            p.last = last[pix];
            for (int c = 0; c < 3; c++) { p.u_rgb[c] = up_rgb[3 * pix + c]; p.u_n[c] = up_normal[3 * pix + c]; }
            p.u_a = up_alpha[pix];
            p.u_d = up_depth[pix];
            for (int c = 0; c < NF; c++) p.u_f[c] = up_feat[(size_t)pix * NF + c];
        }
        for (int c = 0; c < 3; c++) p.b_rgb[c] = o.bg[c] * p.t_final;
        any_geo = any_geo || p.u_d != 0.0f || p.u_n[0] != 0.0f || p.u_n[1] != 0.0f || p.u_n[2] != 0.0f;
        my_last = max(my_last, p.last);
    }
    // Whether any pixel of this warp has a depth or normal gradient: when none has (an RGB-only
    // loss), their terms are exactly zero, so the warp does not compute them (nor add them).
    bool geo = __any_sync(0xffffffffu, any_geo);
    if (tid == 0) max_last = 0;
    __syncthreads();
    atomicMax(&max_last, my_last);
    __syncthreads();
    unsigned end = range.x + max_last;
    // The warp's own last slot and block bit: slots past every lane's last, and Gaussians that
    // reach none of the warp's pixels, are skipped by the whole warp at once.
    unsigned warp_last = __reduce_max_sync(0xffffffffu, my_last);
    unsigned wbit = 1u << (tid >> 5);
    for (unsigned stop = end; stop > range.x;) {
        unsigned start = stop > range.x + BATCH ? stop - BATCH : range.x;
        unsigned cnt = stop - start;
        __syncthreads();
        for (unsigned t = tid; t < cnt; t += BWD_THREADS) {
            unsigned id = vals[start + t];
            sid[t] = id;
            Proj p = proj[id];
            sp[t] = p;
            smask[t] = (unsigned char)warp_blocks<4, 8>(p, blockIdx.x * TILE, blockIdx.y * TILE, SMOOTH);
        }
        __syncthreads();
        unsigned base = start - range.x;
        int top = warp_last <= base ? -1 : (int)min(cnt, warp_last - base) - 1;
        for (int j = top; j >= 0; j--) {
            if (!(smask[j] & wbit)) continue;
            const Proj& g = sp[j];
            unsigned slot = base + (unsigned)j;
            float alpha[2] = {0.0f, 0.0f}, e[2] = {0.0f, 0.0f};
            bool cl[2] = {false, false}, hit[2];
            // Both pixels' tests in straight-line code (`&`, not `&&`): the Gaussian is read from
            // shared memory once, and no branch has to reconverge.
            Hot h = hot_of(g);
#pragma unroll
            for (int k = 0; k < 2; k++)
                hit[k] = (slot < px[k].last) & alpha_at<SMOOTH>(h, px[k].qx, px[k].qy, alpha[k], e[k], cl[k]);
            unsigned hits = __ballot_sync(0xffffffffu, hit[0] || hit[1]);
            if (!hits) continue;
            float fi[NF > 0 ? NF : 1];
            for (int c = 0; c < NF; c++) fi[c] = feats[(size_t)sid[j] * NF + c];
            float v[RED_P];
#pragma unroll
            for (int k = 0; k < RED_P; k++) v[k] = 0.0f;
#pragma unroll
            for (int k = 0; k < 2; k++)
                if (hit[k]) hit_grads(px[k], g, alpha[k], e[k], cl[k], fi, geo, v);
            unsigned long long* dst = g2q + (size_t)sid[j] * G2N;
            if (__popc(hits) <= SPARSE_HITS) {
                if (hit[0] || hit[1]) {
#pragma unroll
                    for (int k = 0; k < 9; k++)
                        if (v[k] != 0.0f) add_fixed(dst + k, v[k], value_scale(k, scale, g.conic), fix_max);
                    if (geo)
#pragma unroll
                        for (int k = 9; k < 13; k++)
                            if (v[k] != 0.0f) add_fixed(dst + k, v[k], scale, fix_max);
#pragma unroll
                    for (int k = 13; k < G2N; k++)
                        if (v[k] != 0.0f) add_fixed(dst + k, v[k], scale, fix_max);
                }
                continue;
            }
            if (NF == 0 && !geo) {
                lean_sum(v, lane);
                // lanes 4k add value k (k < 8), lane 1 value 8: one atomic instruction
                int k = (lane & 3) == 0 ? lane >> 2 : 8;
                float sum = k < 8 ? v[0] : v[8];
                if (((lane & 3) == 0 || lane == 1) && sum != 0.0f)
                    add_fixed(dst + k, sum, value_scale(k, scale, g.conic), fix_max);
                continue;
            }
            spread_sum(v, lane);
            int k = red_index(lane);
            if (red_owner(lane) && k < G2N && v[0] != 0.0f) add_fixed(dst + k, v[0], value_scale(k, scale, g.conic), fix_max);
        }
        stop = start;
    }
}

extern "C" __global__ void __launch_bounds__(BWD_THREADS) raster_backward(BACKWARD_PARAMS) {
    __shared__ Proj sp[BATCH];
    __shared__ unsigned sid[BATCH];
    __shared__ unsigned char smask[BATCH];
    __shared__ unsigned max_last;
    if (o.smooth) backward_tile<true>(BACKWARD_ARGS, sp, sid, smask, max_last);
    else backward_tile<false>(BACKWARD_ARGS, sp, sid, smask, max_last);
}
