// Forward and backward rasterisation (splat::raster and splat::raster_backward, in f32): one
// 16x16 block per tile, one thread per pixel (placed by pixel_of), the tile's depth-sorted
// Gaussians staged through shared memory in batches of 256. The alpha test is
// splat::tiles::alpha_at's.

struct Hot {
    float mean[2], conic[3], opacity, power_min, extent[2];
};

__device__ __forceinline__ bool alpha_at(const Hot& h, float qx, float qy, int smooth, float& alpha, float& e,
                                         bool& clamped) {
    float dx = qx - h.mean[0], dy = qy - h.mean[1];
    if (!smooth && (fabsf(dx) > h.extent[0] || fabsf(dy) > h.extent[1])) return false;
    float power = -0.5f * (h.conic[0] * dx * dx + h.conic[2] * dy * dy) - h.conic[1] * dx * dy;
    if (power > 0.0f || (!smooth && power < h.power_min)) return false;
    e = expf(power);
    float raw = h.opacity * e;
    clamped = !smooth && raw > ALPHA_MAX;
    alpha = clamped ? ALPHA_MAX : raw;
    return smooth || alpha >= ALPHA_MIN;
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
// A warp's 32 pixels are an 8x4 block of the 16x16 tile, not two rows of 16: a small Gaussian
// reaches fewer warps, so fewer warps test it and fewer sum its gradients (the backward 7 % faster
// at 100k Gaussians and 1920x1080 on an H100; each pixel's result is the same either way).
__device__ __forceinline__ void pixel_of(int tid, int& x, int& y) {
    int lane = tid & 31, warp = tid >> 5;
    x = (lane & 7) | ((warp & 1) << 3);
    y = (lane >> 3) | ((warp >> 1) << 2);
}

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

// Which value's sum lane `lane` holds after spread_sum, and whether it adds it (one lane of each
// pair when RED_P is 16).
__device__ __forceinline__ int red_index(int lane) { return RED_P == 32 ? lane : lane >> 1; }
__device__ __forceinline__ bool red_owner(int lane) { return RED_P == 32 || (lane & 1) == 0; }

extern "C" __global__ void __launch_bounds__(256) raster_forward(
    int width, int height, Opts o, const uint2* ranges, const unsigned* vals, const Proj* proj, const float* feats,
    float* out_rgb, float* out_alpha, float* out_depth, float* out_normal, float* out_feat, float* final_t,
    unsigned* last) {
    __shared__ Proj sp[BATCH];
    __shared__ unsigned sid[BATCH];
    int tile = blockIdx.y * gridDim.x + blockIdx.x;
    int tid = threadIdx.y * TILE + threadIdx.x;
    int lx, ly;
    pixel_of(tid, lx, ly);
    int px = blockIdx.x * TILE + lx, py = blockIdx.y * TILE + ly;
    bool inside = px < width && py < height;
    float qx = (float)px + 0.5f, qy = (float)py + 0.5f;
    uint2 range = ranges[tile];
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
            sp[tid] = proj[id];
        }
        __syncthreads();
        unsigned cnt = min((unsigned)BATCH, range.y - start);
        for (unsigned j = 0; j < cnt && !done; j++) {
            const Proj& g = sp[j];
            float alpha, e;
            bool cl;
            if (!alpha_at(hot_of(g), qx, qy, o.smooth, alpha, e, cl)) continue;
            float next = T * (1.0f - alpha);
            if (!o.smooth && next < T_MIN) {
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

extern "C" __global__ void __launch_bounds__(256) raster_backward(
    int width, int height, Opts o, const uint2* ranges, const unsigned* vals, const Proj* proj, const float* feats,
    const float* final_t, const unsigned* last, const float* up_rgb, const float* up_alpha, const float* up_depth,
    const float* up_normal, const float* up_feat, float* g2) {
    __shared__ Proj sp[BATCH];
    __shared__ unsigned sid[BATCH];
    __shared__ unsigned max_last;
    int tile = blockIdx.y * gridDim.x + blockIdx.x;
    int tid = threadIdx.y * TILE + threadIdx.x;
    int lx, ly;
    pixel_of(tid, lx, ly);
    int px = blockIdx.x * TILE + lx, py = blockIdx.y * TILE + ly;
    int lane = tid & 31;
    bool inside = px < width && py < height;
    int pix = py * width + px;
    float qx = (float)px + 0.5f, qy = (float)py + 0.5f;
    uint2 range = ranges[tile];
    float T = 1.0f, t_final = 1.0f;
    unsigned my_last = 0;
    float u_rgb[3] = {0.0f, 0.0f, 0.0f}, u_n[3] = {0.0f, 0.0f, 0.0f}, u_a = 0.0f, u_d = 0.0f;
    float u_f[NF > 0 ? NF : 1], s_f[NF > 0 ? NF : 1];
    for (int c = 0; c < NF; c++) { u_f[c] = 0.0f; s_f[c] = 0.0f; }
    if (inside) {
        T = t_final = final_t[pix];
        my_last = last[pix];
        for (int c = 0; c < 3; c++) { u_rgb[c] = up_rgb[3 * pix + c]; u_n[c] = up_normal[3 * pix + c]; }
        u_a = up_alpha[pix];
        u_d = up_depth[pix];
        for (int c = 0; c < NF; c++) u_f[c] = up_feat[(size_t)pix * NF + c];
    }
    float b_rgb[3] = {o.bg[0] * t_final, o.bg[1] * t_final, o.bg[2] * t_final}, b_n[3] = {0.0f, 0.0f, 0.0f},
          b_d = 0.0f;
    // Whether any pixel of this warp has a depth or normal gradient: when none has (an RGB-only
    // loss), their terms are exactly zero, so the warp does not compute them (nor add them).
    bool geo = __any_sync(0xffffffffu, u_d != 0.0f || u_n[0] != 0.0f || u_n[1] != 0.0f || u_n[2] != 0.0f);
    if (tid == 0) max_last = 0;
    __syncthreads();
    atomicMax(&max_last, my_last);
    __syncthreads();
    unsigned end = range.x + max_last;
    for (unsigned stop = end; stop > range.x;) {
        unsigned start = stop > range.x + BATCH ? stop - BATCH : range.x;
        unsigned cnt = stop - start;
        __syncthreads();
        if (tid < cnt) {
            unsigned id = vals[start + tid];
            sid[tid] = id;
            sp[tid] = proj[id];
        }
        __syncthreads();
        for (int j = (int)cnt - 1; j >= 0; j--) {
            const Proj& g = sp[j];
            unsigned slot = start - range.x + (unsigned)j;
            float alpha = 0.0f, e = 0.0f;
            bool cl = false;
            bool hit = slot < my_last && alpha_at(hot_of(g), qx, qy, o.smooth, alpha, e, cl);
            unsigned hits = __ballot_sync(0xffffffffu, hit);
            if (!hits) continue;
            float v[RED_P];
#pragma unroll
            for (int k = 0; k < RED_P; k++) v[k] = 0.0f;
            if (hit) {
                float inv = 1.0f / (1.0f - alpha);
                float ti = T * inv;
                float w = alpha * ti;
                float vc[3];
                for (int c = 0; c < 3; c++) {
                    vc[c] = fmaxf(g.color[c], 0.0f);
                    if (g.color[c] > 0.0f) v[6 + c] = u_rgb[c] * w;
                }
                float d_alpha = u_a * t_final * inv;
                for (int c = 0; c < 3; c++) d_alpha += u_rgb[c] * (ti * vc[c] - b_rgb[c] * inv);
                if (geo) {
                    v[9] = u_d * w;
                    d_alpha += u_d * (ti * g.depth - b_d * inv);
                    for (int c = 0; c < 3; c++) {
                        v[10 + c] = u_n[c] * w;
                        d_alpha += u_n[c] * (ti * g.normal[c] - b_n[c] * inv);
                        b_n[c] += w * g.normal[c];
                    }
                    b_d += w * g.depth;
                }
                for (int c = 0; c < NF; c++) {
                    float fi = feats[(size_t)sid[j] * NF + c];
                    v[13 + c] = u_f[c] * w;
                    d_alpha += u_f[c] * (ti * fi - s_f[c] * inv);
                    s_f[c] += w * fi;
                }
                for (int c = 0; c < 3; c++) b_rgb[c] += w * vc[c];
                if (!cl) {
                    v[5] = d_alpha * e;
                    float dp = d_alpha * alpha;
                    float dx = qx - g.mean[0], dy = qy - g.mean[1];
                    v[2] = dp * -0.5f * dx * dx;
                    v[3] = dp * -dx * dy;
                    v[4] = dp * -0.5f * dy * dy;
                    v[0] = dp * (g.conic[0] * dx + g.conic[1] * dy);
                    v[1] = dp * (g.conic[1] * dx + g.conic[2] * dy);
                }
                T = ti;
            }
            if (__popc(hits) <= SPARSE_HITS) {
                if (hit) {
                    float* dst = g2 + (size_t)sid[j] * G2N;
#pragma unroll
                    for (int k = 0; k < 9; k++)
                        if (v[k] != 0.0f) atomicAdd(dst + k, v[k]);
                    if (geo)
#pragma unroll
                        for (int k = 9; k < 13; k++)
                            if (v[k] != 0.0f) atomicAdd(dst + k, v[k]);
#pragma unroll
                    for (int k = 13; k < G2N; k++)
                        if (v[k] != 0.0f) atomicAdd(dst + k, v[k]);
                }
                continue;
            }
            spread_sum(v, lane);
            int k = red_index(lane);
            if (red_owner(lane) && k < G2N && v[0] != 0.0f) atomicAdd(&g2[(size_t)sid[j] * G2N + k], v[0]);
        }
        stop = start;
    }
}
