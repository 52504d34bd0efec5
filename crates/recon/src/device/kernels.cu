// The trainer's per-iteration work on the device (recon::device): composing the scene at the
// view's time, the way back from world-frame gradients to each model's parameters (with the
// flattening term and the density statistics), and Adam; the view loss and its gradients with
// respect to the rendered channels follow in loss.cu and ssim.cu. Every formula mirrors the f64
// host code it names, in f32.

// camera_from_world rotation (rows) and pinhole intrinsics.
struct CamK {
    float r[9];
    float fx, fy, cx, cy;
    int width, height;
};

// An actor's world_from_box at the view's time: yaw rotation R, translation t, the yaw
// quaternion's (cos, sin) of half the angle, and the SH rotation M (16 x 16, row = world
// coefficient, column = box coefficient).
struct Xf {
    float r[9];
    float t[3];
    float c, s;
    float m[256];
};

// A warp's sum of `v` added to a loss sum in fixed point (units of 2^-ACC_BITS; the host's
// `loss::ACC_BITS`): integer atomics add in any order to the same total, so the reported loss is
// the same every run (float atomics made it differ in its last bits). A pixel's loss terms are
// at most a few units of 1 (the flattening term: a scale in metres), so a sum over millions of
// pixels stays far below 2^(63 - ACC_BITS) = 2.1e9.
// A non-finite sum sets acc[ACC_NAN] instead (the host then reports the loss as NaN).
#define ACC_BITS 32
#define ACC_NAN 7
__device__ __forceinline__ void warp_add(unsigned long long* acc, int k, float v) {
    for (int off = 16; off > 0; off >>= 1) v += __shfl_down_sync(0xffffffffu, v, off);
    if ((threadIdx.x & 31) != 0) return;
    if (!isfinite(v)) atomicOr(acc + ACC_NAN, 1ull);
    else if (long long q = __float2ll_rn(ldexpf(v, ACC_BITS)); q != 0) atomicAdd(acc + k, (unsigned long long)q);
}

// A run of world rows: model rows src0..src0+n drawn at world rows dst0.., moved by x when
// `moved` (the background is drawn as it is). The table holds only non-empty runs, in world order.
struct Seg {
    int src0, dst0, n, moved;
    Xf x;
};

// The run holding world row o (the last with dst0 <= o).
__device__ __forceinline__ const Seg* seg_of(const Seg* segs, int nseg, int o) {
    int lo = 0, hi = nseg - 1;
    while (lo < hi) {
        int mid = (lo + hi + 1) >> 1;
        if (segs[mid].dst0 <= o) lo = mid;
        else hi = mid - 1;
    }
    return segs + lo;
}

// ---- compose (recon::compose::compose_into): one thread per world row, every run at once;
// the SH coefficients in compose_sh ----

extern "C" __global__ void compose_rows(int n_world, int nseg, const Seg* __restrict__ segs, const float* means,
                                        const float* log_scales, const float* rots, const float* logits,
                                        float* w_means, float* w_log_scales, float* w_rots, float* w_logits) {
    int o = blockIdx.x * blockDim.x + threadIdx.x;
    if (o >= n_world) return;
    const Seg* g = seg_of(segs, nseg, o);
    const Xf& x = g->x;
    size_t i = (size_t)g->src0 + (o - g->dst0);
    const float* m = means + 3 * i;
    const float* q = rots + 4 * i;
    for (int a = 0; a < 3; a++) w_log_scales[3 * (size_t)o + a] = log_scales[3 * i + a];
    w_logits[o] = logits[i];
    if (!g->moved) {
        for (int a = 0; a < 3; a++) w_means[3 * (size_t)o + a] = m[a];
        for (int a = 0; a < 4; a++) w_rots[4 * (size_t)o + a] = q[a];
        return;
    }
    for (int a = 0; a < 3; a++)
        w_means[3 * (size_t)o + a] = x.r[3 * a] * m[0] + x.r[3 * a + 1] * m[1] + x.r[3 * a + 2] * m[2] + x.t[a];
    w_rots[4 * (size_t)o] = x.c * q[0] - x.s * q[3];
    w_rots[4 * (size_t)o + 1] = x.c * q[1] - x.s * q[2];
    w_rots[4 * (size_t)o + 2] = x.c * q[2] + x.s * q[1];
    w_rots[4 * (size_t)o + 3] = x.c * q[3] + x.s * q[0];
}

// The SH coefficients of compose_rows, one thread per world float (row o, float f of its
// kc_act * 3): neighbouring threads write neighbouring floats (a thread per row wrote 48 floats
// 192 bytes apart from its neighbour's).
extern "C" __global__ void compose_sh(int n_world, int nseg, const Seg* __restrict__ segs, int kc_full, int kc_act,
                                      const float* sh, float* w_sh) {
    int width = kc_act * 3;
    size_t idx = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (idx >= (size_t)n_world * width) return;
    int o = (int)(idx / width), f = (int)(idx % width);
    const Seg* g = seg_of(segs, nseg, o);
    const float* c = sh + ((size_t)g->src0 + (o - g->dst0)) * kc_full * 3;
    if (!g->moved) {
        w_sh[idx] = c[f];
        return;
    }
    int ko = f / 3, ch = f % 3;
    float acc = 0.0f;
    for (int ki = 0; ki < kc_full; ki++) acc += g->x.m[ko * 16 + ki] * c[ki * 3 + ch];
    w_sh[idx] = acc;
}

// ---- back to the models (recon::compose::scatter_gradients), the flattening term and the
// density statistics (recon::train::Trainer::step, recon::densify::Stats::record); counts[1] is
// the number of Gaussians drawn, acc[6] collects the sum of their smallest scales. One thread per
// world row; every lane reaches the warp sum; the SH gradients in scatter_sh ----

extern "C" __global__ void scatter_rows(int n_world, int nseg, const Seg* __restrict__ segs,
                                        const float* gw_means, const float* gw_log_scales,
                                        const float* gw_rots, const float* gw_logits, const float* gw_mean2d, const int* valid, const float* proj,
                                        int proj_floats, int proj_extent, const float* log_scales, float flat_w,
                                        const unsigned* counts, int densifying, float half_side, float* g_means,
                                        float* g_log_scales, float* g_rots, float* g_logits, float* grad_sum, unsigned* seen, float* max_radius, unsigned long long* acc) {
    int o = blockIdx.x * blockDim.x + threadIdx.x;
    float e = 0.0f;
    if (o < n_world) {
        const Seg* sg = seg_of(segs, nseg, o);
        const Xf& x = sg->x;
        size_t i = (size_t)sg->src0 + (o - sg->dst0);
        for (int a = 0; a < 3; a++) g_log_scales[3 * i + a] = gw_log_scales[3 * (size_t)o + a];
        g_logits[i] = gw_logits[o];
        const float* gm = gw_means + 3 * (size_t)o;
        const float* gq = gw_rots + 4 * (size_t)o;
        if (!sg->moved) {
            for (int a = 0; a < 3; a++) g_means[3 * i + a] = gm[a];
            for (int a = 0; a < 4; a++) g_rots[4 * i + a] = gq[a];
        } else {
            for (int a = 0; a < 3; a++)
                g_means[3 * i + a] = x.r[a] * gm[0] + x.r[3 + a] * gm[1] + x.r[6 + a] * gm[2];
            g_rots[4 * i] = x.c * gq[0] + x.s * gq[3];
            g_rots[4 * i + 1] = x.c * gq[1] + x.s * gq[2];
            g_rots[4 * i + 2] = -x.s * gq[1] + x.c * gq[2];
            g_rots[4 * i + 3] = -x.s * gq[0] + x.c * gq[3];
        }
        if (valid[o]) {
            const float* ls = log_scales + 3 * i;
            int k = 0;
            float lmin = ls[0];
            for (int a = 1; a < 3; a++)
                if (ls[a] < lmin) { lmin = ls[a]; k = a; }
            e = expf(lmin);
            float nv = (float)max(counts[1], 1u);
            g_log_scales[3 * i + k] += flat_w * e / nv;
            if (densifying) {
                grad_sum[i] += gw_mean2d[o] * half_side;
                seen[i] += 1u;
                const float* ext = proj + (size_t)o * proj_floats + proj_extent;
                max_radius[i] = fmaxf(max_radius[i], fmaxf(ext[0], ext[1]));
            }
        }
    }
    warp_add(acc, 6, e);
}

// The SH gradients of scatter_rows, one thread per model float (world row o, float f of its
// kc_full * 3; coefficients above kc_act get 0), coalesced as in compose_sh.
extern "C" __global__ void scatter_sh(int n_world, int nseg, const Seg* __restrict__ segs, int kc_full, int kc_act,
                                      const float* gw_sh, float* g_sh) {
    int width = kc_full * 3;
    size_t idx = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (idx >= (size_t)n_world * width) return;
    int o = (int)(idx / width), f = (int)(idx % width);
    const Seg* g = seg_of(segs, nseg, o);
    size_t i = (size_t)g->src0 + (o - g->dst0);
    const float* gs = gw_sh + (size_t)o * kc_act * 3;
    float v = 0.0f;
    if (!g->moved) {
        if (f < kc_act * 3) v = gs[f];
    } else {
        int ki = f / 3, ch = f % 3;
        for (int ko = 0; ko < kc_act; ko++) v += g->x.m[ko * 16 + ki] * gs[ko * 3 + ch];
    }
    g_sh[i * width + f] = v;
}

// How many Gaussians the forward pass drew, into counts[1].
extern "C" __global__ void count_valid(int n, const int* valid, unsigned* counts) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    unsigned v = (i < n && valid[i]) ? 1u : 0u;
    v = __reduce_add_sync(0xffffffffu, v);
    if ((threadIdx.x & 31) == 0 && v) atomicAdd(&counts[1], v);
}

// ---- Adam (recon::optim) ----
// Rate `lr_a`, or `lr_b` for the elements whose index modulo `k` is 3 or more (SH beyond DC)
// when k > 0.
extern "C" __global__ void adam(size_t n, float* p, const float* g, float* m, float* v, float lr_a, float lr_b,
                                int k, float bc1, float bc2) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    float gi = g[i];
    float mi = 0.9f * m[i] + 0.1f * gi;
    float vi = 0.999f * v[i] + 0.001f * gi * gi;
    m[i] = mi;
    v[i] = vi;
    float lr = (k > 0 && (int)(i % (size_t)k) >= 3) ? lr_b : lr_a;
    p[i] -= lr * (mi / bc1) / (sqrtf(vi / bc2) + 1e-15f);
}
