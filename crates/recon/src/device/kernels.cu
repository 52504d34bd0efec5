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
// A `mirror` run draws its rows' mirror images about the box's x-z plane (recon::compose::
// mirror_row: y negated, the quaternion's x and z negated; the y-odd SH columns of x.m negated on
// the host); the run it mirrors names it in `twin` (-1: none), and the way back handles both runs'
// rows in the unmirrored run's threads, so every model row is written by one thread.
struct Seg {
    int src0, dst0, n, moved, mirror, twin;
    Xf x;
};

// recon::smoothing::filtered: a row's log-scales and logit convolved with a filter of variance f2.
__device__ __forceinline__ void smoothed(const float* ls, float logit, float f2, float* ls_out, float* logit_out) {
    float c = 1.0f;
    for (int a = 0; a < 3; a++) {
        float s2 = expf(2.0f * ls[a]);
        ls_out[a] = 0.5f * logf(s2 + f2);
        c *= s2 / (s2 + f2);
    }
    c = sqrtf(c);
    float sig = 1.0f / (1.0f + expf(-logit));
    float om = 1.0f / (1.0f + expf(logit)) + sig * (1.0f - c);
    *logit_out = logf(sig * c) - logf(om);
}

// recon::smoothing::filtered_grad: gradients on the filtered values back to the row's own.
__device__ __forceinline__ void smoothed_grad(const float* ls, float logit, float f2, float* g_ls, float* g_logit) {
    float s2[3], c = 1.0f;
    for (int a = 0; a < 3; a++) {
        s2[a] = expf(2.0f * ls[a]);
        c *= s2[a] / (s2[a] + f2);
    }
    c = sqrtf(c);
    float sig = 1.0f / (1.0f + expf(-logit)), one_minus_sig = 1.0f / (1.0f + expf(logit));
    float om = one_minus_sig + sig * (1.0f - c);
    float gl = *g_logit;
    for (int a = 0; a < 3; a++) g_ls[a] = g_ls[a] * s2[a] / (s2[a] + f2) + gl * f2 / ((s2[a] + f2) * om);
    *g_logit = gl * one_minus_sig / om;
}

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

// `f2` (may be null: no smoothing) holds each model row's smoothing variance (recon::smoothing).
extern "C" __global__ void compose_rows(int n_world, int nseg, const Seg* __restrict__ segs, const float* means,
                                        const float* log_scales, const float* rots, const float* logits,
                                        const float* f2, float* w_means, float* w_log_scales, float* w_rots,
                                        float* w_logits) {
    int o = blockIdx.x * blockDim.x + threadIdx.x;
    if (o >= n_world) return;
    const Seg* g = seg_of(segs, nseg, o);
    const Xf& x = g->x;
    size_t i = (size_t)g->src0 + (o - g->dst0);
    float my = g->mirror ? -1.0f : 1.0f;
    float m[3] = {means[3 * i], my * means[3 * i + 1], means[3 * i + 2]};
    float q[4] = {rots[4 * i], my * rots[4 * i + 1], rots[4 * i + 2], my * rots[4 * i + 3]};
    if (f2) {
        smoothed(log_scales + 3 * i, logits[i], f2[i], w_log_scales + 3 * (size_t)o, w_logits + o);
    } else {
        for (int a = 0; a < 3; a++) w_log_scales[3 * (size_t)o + a] = log_scales[3 * i + a];
        w_logits[o] = logits[i];
    }
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

// `logits` and `f2` (may be null: no smoothing) give each model row's own logit and smoothing
// variance for the filter's Jacobian. A mirror run's threads do nothing but join the warp sum: its
// twin's threads add both rows (mirrored back: y, the quaternion's x and z negated) in a fixed order.
extern "C" __global__ void scatter_rows(int n_world, int nseg, const Seg* __restrict__ segs,
                                        const float* gw_means, const float* gw_log_scales,
                                        const float* gw_rots, const float* gw_logits, const float* gw_mean2d, const int* valid, const float* proj,
                                        int proj_floats, int proj_extent, const float* log_scales, const float* logits,
                                        const float* f2, float flat_w,
                                        const unsigned* counts, int densifying, float half_side, float* g_means,
                                        float* g_log_scales, float* g_rots, float* g_logits, float* grad_sum, unsigned* seen, float* max_radius, unsigned long long* acc) {
    int o = blockIdx.x * blockDim.x + threadIdx.x;
    float e = 0.0f;
    const Seg* sg = o < n_world ? seg_of(segs, nseg, o) : nullptr;
    if (sg && !sg->mirror) {
        const Xf& x = sg->x;
        size_t i = (size_t)sg->src0 + (o - sg->dst0);
        int ot = sg->twin >= 0 ? segs[sg->twin].dst0 + (o - sg->dst0) : -1;
        int rows[2] = {o, ot};
        float gls[3] = {0.0f, 0.0f, 0.0f}, glog = 0.0f, gmean[3] = {0.0f, 0.0f, 0.0f}, grot[4] = {0.0f, 0.0f, 0.0f, 0.0f};
        for (int k = 0; k < 2; k++) {
            int w = rows[k];
            if (w < 0) continue;
            float my = k == 1 ? -1.0f : 1.0f;
            for (int a = 0; a < 3; a++) gls[a] += gw_log_scales[3 * (size_t)w + a];
            glog += gw_logits[w];
            const float* gm = gw_means + 3 * (size_t)w;
            const float* gq = gw_rots + 4 * (size_t)w;
            float lm[3], lq[4];
            if (!sg->moved) {
                for (int a = 0; a < 3; a++) lm[a] = gm[a];
                for (int a = 0; a < 4; a++) lq[a] = gq[a];
            } else {
                for (int a = 0; a < 3; a++) lm[a] = x.r[a] * gm[0] + x.r[3 + a] * gm[1] + x.r[6 + a] * gm[2];
                lq[0] = x.c * gq[0] + x.s * gq[3];
                lq[1] = x.c * gq[1] + x.s * gq[2];
                lq[2] = -x.s * gq[1] + x.c * gq[2];
                lq[3] = -x.s * gq[0] + x.c * gq[3];
            }
            gmean[0] += lm[0];
            gmean[1] += my * lm[1];
            gmean[2] += lm[2];
            grot[0] += lq[0];
            grot[1] += my * lq[1];
            grot[2] += lq[2];
            grot[3] += my * lq[3];
        }
        if (f2) smoothed_grad(log_scales + 3 * i, logits[i], f2[i], gls, &glog);
        for (int a = 0; a < 3; a++) g_log_scales[3 * i + a] = gls[a];
        g_logits[i] = glog;
        for (int a = 0; a < 3; a++) g_means[3 * i + a] = gmean[a];
        for (int a = 0; a < 4; a++) g_rots[4 * i + a] = grot[a];
        for (int k = 0; k < 2; k++) {
            int w = rows[k];
            if (w < 0 || !valid[w]) continue;
            const float* ls = log_scales + 3 * i;
            int km = 0;
            float lmin = ls[0];
            for (int a = 1; a < 3; a++)
                if (ls[a] < lmin) { lmin = ls[a]; km = a; }
            float ek = expf(lmin);
            e += ek;
            float nv = (float)max(counts[1], 1u);
            g_log_scales[3 * i + km] += flat_w * ek / nv;
            if (densifying) {
                grad_sum[i] += gw_mean2d[w] * half_side;
                seen[i] += 1u;
                const float* ext = proj + (size_t)w * proj_floats + proj_extent;
                max_radius[i] = fmaxf(max_radius[i], fmaxf(ext[0], ext[1]));
            }
        }
    }
    warp_add(acc, 6, e);
}

// The SH gradients of scatter_rows, one thread per model float (world row o, float f of its
// kc_full * 3; coefficients above kc_act get 0), coalesced as in compose_sh.
// A mirror run's floats are added by its twin's threads (with the mirror's own SH rotation, whose
// y-odd columns are negated), so each model float is written once.
extern "C" __global__ void scatter_sh(int n_world, int nseg, const Seg* __restrict__ segs, int kc_full, int kc_act,
                                      const float* gw_sh, float* g_sh) {
    int width = kc_full * 3;
    size_t idx = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (idx >= (size_t)n_world * width) return;
    int o = (int)(idx / width), f = (int)(idx % width);
    const Seg* g = seg_of(segs, nseg, o);
    if (g->mirror) return;
    size_t i = (size_t)g->src0 + (o - g->dst0);
    const float* gs = gw_sh + (size_t)o * kc_act * 3;
    float v = 0.0f;
    if (!g->moved) {
        if (f < kc_act * 3) v = gs[f];
    } else {
        int ki = f / 3, ch = f % 3;
        for (int ko = 0; ko < kc_act; ko++) v += g->x.m[ko * 16 + ki] * gs[ko * 3 + ch];
        if (g->twin >= 0) {
            const Seg* t = segs + g->twin;
            const float* gt = gw_sh + (size_t)(t->dst0 + (o - g->dst0)) * kc_act * 3;
            for (int ko = 0; ko < kc_act; ko++) v += t->x.m[ko * 16 + ki] * gt[ko * 3 + ch];
        }
    }
    g_sh[i * width + f] = v;
}

// ---- the 3D smoothing filter (recon::smoothing): each row's finest sampling rate over its set's
// training views, then its variance ----

// One view of one set: camera_from_set rows (3 x 4), intrinsics, image size.
struct Sampler {
    float m[12];
    float fx, fy, cx, cy, w, h;
};

__device__ __forceinline__ float sampler_rate(const Sampler& v, float x, float y, float z) {
    float q[3];
    for (int r = 0; r < 3; r++) q[r] = v.m[4 * r] * x + v.m[4 * r + 1] * y + v.m[4 * r + 2] * z + v.m[4 * r + 3];
    if (!(q[2] > 0.2f)) return 0.0f;
    float u = v.fx * q[0] / q[2] + v.cx, t = v.fy * q[1] / q[2] + v.cy;
    bool inside = u >= -0.15f * v.w && u <= 1.15f * v.w && t >= -0.15f * v.h && t <= 1.15f * v.h;
    return inside ? fmaxf(v.fx, v.fy) / q[2] : 0.0f;
}

// rate[i]: the finest rate of row i (0: unseen); rate_min: the smallest positive rate of all rows
// (float bits, which order as integers for positive floats; 0xffffffff: none). `sets` holds, per
// set, its first row, its first sampler, its sampler count and whether it is mirrored. Rows before
// `first_row` (the background, when the filter is on the actors alone) get rate -1: no filter.
extern "C" __global__ void smooth_rates(int n, int nsets, int first_row, const int* sets, const Sampler* samplers,
                                        const float* means, float* rate, unsigned* rate_min) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    unsigned key = 0xffffffffu;
    if (i < n) {
        int lo = 0, hi = nsets - 1;
        while (lo < hi) {
            int mid = (lo + hi + 1) >> 1;
            if (sets[4 * mid] <= i) lo = mid;
            else hi = mid - 1;
        }
        const int* st = sets + 4 * lo;
        float x = means[3 * (size_t)i], y = means[3 * (size_t)i + 1], z = means[3 * (size_t)i + 2];
        float r = 0.0f;
        for (int k = 0; k < st[2]; k++) {
            const Sampler& v = samplers[st[1] + k];
            r = fmaxf(r, sampler_rate(v, x, y, z));
            if (st[3]) r = fmaxf(r, sampler_rate(v, x, -y, z));
        }
        if (i < first_row) r = -1.0f;
        rate[i] = r;
        if (r > 0.0f) key = __float_as_uint(r);
    }
    key = __reduce_min_sync(0xffffffffu, key);
    if ((threadIdx.x & 31) == 0 && key != 0xffffffffu) atomicMin(rate_min, key);
}

// The variances from the rates (in place): factor / rate^2, and for unseen rows the largest of the
// seen rows' (factor / rate_min^2; 0 when no row is seen).
extern "C" __global__ void smooth_finish(int n, float factor, const unsigned* rate_min, float* f2) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    float r = f2[i];
    unsigned km = *rate_min;
    float rmin = km == 0xffffffffu ? 0.0f : __uint_as_float(km);
    float use = r > 0.0f ? r : rmin;
    f2[i] = r < 0.0f ? 0.0f : use > 0.0f ? factor / (use * use) : 0.0f;
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
