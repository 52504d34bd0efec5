// The view loss on the device (recon::loss::view_loss, term for term), compiled after kernels.cu
// (CamK, warp_add) and before ssim.cu: the sky's bilinear taps, the composite with the sky and
// L1, the photometric gradient through the composite to RGB, alpha and the sky texels, relative
// depth L1, `L_normal`, and `L_geo` with its pooled-normal adjoint. `loss.rs` launches them.

// ---- the sky (recon::sky::Sky::taps) ----

__device__ void sky_taps(int res, float x, float y, float z, int* idx, float* w) {
    float ax = fabsf(x), ay = fabsf(y), az = fabsf(z);
    int face;
    float s, t;
    if (ax >= ay && ax >= az) {
        if (x > 0.0f) { face = 0; s = -y / ax; t = -z / ax; }
        else { face = 1; s = y / ax; t = -z / ax; }
    } else if (ay >= az) {
        if (y > 0.0f) { face = 2; s = x / ay; t = -z / ay; }
        else { face = 3; s = -x / ay; t = -z / ay; }
    } else {
        float a = fmaxf(az, 1e-30f);
        if (z > 0.0f) { face = 4; s = -y / a; t = x / a; }
        else { face = 5; s = -y / a; t = -x / a; }
    }
    float nres = (float)res;
    float fu = fminf(fmaxf((s + 1.0f) * 0.5f * nres - 0.5f, 0.0f), nres - 1.0f);
    float fv = fminf(fmaxf((t + 1.0f) * 0.5f * nres - 0.5f, 0.0f), nres - 1.0f);
    int u0 = (int)floorf(fu), v0 = (int)floorf(fv);
    int u1 = min(u0 + 1, res - 1), v1 = min(v0 + 1, res - 1);
    float wu = fu - (float)u0, wv = fv - (float)v0;
    int base = face * res * res;
    idx[0] = base + v0 * res + u0; w[0] = (1.0f - wu) * (1.0f - wv);
    idx[1] = base + v0 * res + u1; w[1] = wu * (1.0f - wv);
    idx[2] = base + v1 * res + u0; w[2] = (1.0f - wu) * wv;
    idx[3] = base + v1 * res + u1; w[3] = wu * wv;
}

// recon::camera::pixel_ray: the unit world direction through pixel i's centre.
__device__ void pixel_taps(const CamK& cam, int i, int res, int* idx, float* w) {
    int px = i % cam.width, py = i / cam.width;
    float d[3] = {((float)px + 0.5f - cam.cx) / cam.fx, ((float)py + 0.5f - cam.cy) / cam.fy, 1.0f};
    float v[3];
    for (int c = 0; c < 3; c++) v[c] = cam.r[c] * d[0] + cam.r[3 + c] * d[1] + cam.r[6 + c] * d[2];
    float nv = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    sky_taps(res, v[0] / nv, v[1] / nv, v[2] / nv, idx, w);
}

// ---- the view loss (recon::loss::view_loss) ----
// acc: 0 sum |out - target|, 1 sum (out - target)^2, 2 sum SSIM map (all channels), 3 depth,
// 4 normal, 5 geo, 6 flattening (sum of the smallest scale).

// Composite with the sky, L1 and its gradient (SSIM: ssim.cu).
// `keep` (may be null: every pixel) is 0 where a pixel is left out of training (recon::protocol):
// its L1 term and gradient are zero; the squared error (the reported PSNR) counts every pixel.
extern "C" __global__ void photo_l1(int p, CamK cam, int sky_res, const float* sky, const float* rgb,
                                    const float* alpha, const float* target, const float* keep, float w_l1,
                                    float* out, float* g_out, unsigned long long* acc) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    float l1 = 0.0f, sq = 0.0f;
    if (i < p) {
        int idx[4];
        float w[4];
        pixel_taps(cam, i, sky_res, idx, w);
        float a = alpha[i], kp = keep ? keep[i] : 1.0f;
        for (int c = 0; c < 3; c++) {
            float s = 0.0f;
            for (int k = 0; k < 4; k++) s += w[k] * sky[idx[k] * 3 + c];
            float x = rgb[3 * i + c] + s * (1.0f - a), y = target[3 * i + c];
            float d = x - y;
            l1 += kp * fabsf(d);
            sq += d * d;
            out[3 * i + c] = x;
            g_out[3 * i + c] = kp * w_l1 * copysignf(1.0f, d);
        }
    }
    warp_add(acc, 0, l1);
    warp_add(acc, 1, sq);
}

// The photometric gradient on the composite, then through the composite to RGB, alpha and the
// sky texels. Thousands of sky pixels share a texel, so the texel gradients are summed per warp
// first (lanes with the same texel, `__match_any_sync`) and only the lowest such lane adds to
// global memory: one atomic per distinct texel, tap and channel instead of one per pixel. The
// texel sums are kept in fixed point (`sky_q`, `sky_scale` units; see `sky_dequantize`), so they
// are the same whatever order the warps add in. Launched with 256 threads a block (`linear`);
// every lane reaches the warp-wide calls.
extern "C" __global__ void photo_grad(int p, CamK cam, int sky_res, const float* sky, const float* alpha,
                                      const float* out, const float* target, const float* bterms, float w_ssim,
                                      const float* g_out, float* up_rgb, float* up_alpha, float sky_scale,
                                      unsigned long long* sky_q) {
    __shared__ float stage[8][32][3];
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    int lane = threadIdx.x & 31, wid = threadIdx.x >> 5;
    int idx[4] = {-1, -1, -1, -1};
    float w[4] = {0.0f, 0.0f, 0.0f, 0.0f}, gs[3] = {0.0f, 0.0f, 0.0f};
    if (i < p) {
        pixel_taps(cam, i, sky_res, idx, w);
        float a = alpha[i], ga = 0.0f;
        for (int c = 0; c < 3; c++) {
            const float* t = bterms + (size_t)c * 3 * p;
            float x = out[3 * i + c], y = target[3 * i + c];
            float g = g_out[3 * i + c] - w_ssim / 3.0f * (t[i] + 2.0f * x * t[p + i] + y * t[2 * p + i]);
            float s = 0.0f;
            for (int k = 0; k < 4; k++) s += w[k] * sky[idx[k] * 3 + c];
            up_rgb[3 * i + c] = g;
            ga -= g * s;
            gs[c] = g * (1.0f - a);
        }
        up_alpha[i] = ga;
    }
    bool any = gs[0] != 0.0f || gs[1] != 0.0f || gs[2] != 0.0f;
    for (int k = 0; k < 4; k++) {
        int key = any && w[k] != 0.0f ? idx[k] : -1;
        unsigned peers = __match_any_sync(0xffffffffu, key);
        for (int c = 0; c < 3; c++) stage[wid][lane][c] = w[k] * gs[c];
        __syncwarp();
        if (key >= 0 && lane == __ffs(peers) - 1) {
            float sum[3] = {0.0f, 0.0f, 0.0f};
            for (unsigned m = peers; m; m &= m - 1) {
                int l = __ffs(m) - 1;
                for (int c = 0; c < 3; c++) sum[c] += stage[wid][l][c];
            }
            for (int c = 0; c < 3; c++) {
                if (isnan(sum[c])) atomicOr(sky_q + 6 * sky_res * sky_res * 3, 1ull);  // the NaN flag
                else if (long long q = __float2ll_rn(sum[c] * sky_scale); q != 0)
                    atomicAdd(sky_q + key * 3 + c, (unsigned long long)q);
            }
        }
        __syncwarp();
    }
}

// The sky's texel gradients (n values, then the NaN flag) from fixed point. The photometric
// loss is a mean over the view's 3p values, so a pixel's gradient is of the order of 1/(3p):
// the host sets sky_scale = 2^28 * 2^ceil(log2(3p)), a unit of about 2^-28 / (3p), and a texel's
// sum over every pixel stays some 2^35 units below where it could wrap.
extern "C" __global__ void sky_dequantize(int n, const unsigned long long* q, float sky_scale, float* grad) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    grad[i] = q[n] != 0 ? __uint_as_float(0x7fffffffu) : __ll2float_rn((long long)q[i]) / sky_scale;
}

// Relative depth L1 where the prior has a value; `scale` = weight / valid count.
extern "C" __global__ void depth_loss(int p, const float* depth, const float* prior, float scale, float inv_valid,
                                      float* up_depth, unsigned long long* acc) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    float l = 0.0f;
    if (i < p) {
        float dp = prior[i], g = 0.0f;
        if (dp > 0.0f) {
            float d = depth[i] - dp;
            l = fabsf(d) / dp * inv_valid;
            g = scale * copysignf(1.0f, d) / dp;
        }
        up_depth[i] = g;
    }
    warp_add(acc, 3, l);
}

// Unit rendered normals (x, y, z, |n|) and how many pixels the normal term uses (the reference
// is zero outside the supervision mask).
extern "C" __global__ void normal_unit(int p, const float* normal, const float* nref, float* unit,
                                       unsigned* count) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    unsigned used = 0;
    if (i < p) {
        float v[3] = {normal[3 * i], normal[3 * i + 1], normal[3 * i + 2]};
        float n = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        bool ok = n > 1e-12f;
        for (int c = 0; c < 3; c++) unit[4 * i + c] = ok ? v[c] / n : 0.0f;
        unit[4 * i + 3] = ok ? n : 0.0f;
        if (nref) {
            bool has = nref[3 * i] != 0.0f || nref[3 * i + 1] != 0.0f || nref[3 * i + 2] != 0.0f;
            used = ok && has ? 1u : 0u;
        }
    }
    used = __reduce_add_sync(0xffffffffu, used);
    if ((threadIdx.x & 31) == 0 && used) atomicAdd(count, used);
}

// L_normal's gradient on the unit normals (into g_unit, which this writes for every pixel).
extern "C" __global__ void normal_terms(int p, const float* unit, const float* nref, float weight,
                                        const unsigned* count, float* g_unit, unsigned long long* acc) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    float l = 0.0f;
    if (i < p) {
        float g[3] = {0.0f, 0.0f, 0.0f};
        unsigned cnt = *count;
        if (nref && cnt > 0 && unit[4 * i + 3] > 0.0f) {
            const float* r = nref + 3 * i;
            if (r[0] != 0.0f || r[1] != 0.0f || r[2] != 0.0f) {
                float s = 1.0f / (float)cnt;
                const float* u = unit + 4 * i;
                l = (1.0f - (u[0] * r[0] + u[1] * r[1] + u[2] * r[2])) * s;
                for (int c = 0; c < 3; c++) g[c] = -weight * s * r[c];
            }
        }
        for (int c = 0; c < 3; c++) g_unit[3 * i + c] = g[c];
    }
    warp_add(acc, 4, l);
}

// nbar = normalize(avgpool3x3(unit)) (zero padding, / 9), as (x, y, z, |m|).
extern "C" __global__ void geo_pool(int width, int height, const float* unit, float* nbar) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= width * height) return;
    int x = i % width, y = i / width;
    float s[3] = {0.0f, 0.0f, 0.0f};
    for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++) {
            int xx = x + dx, yy = y + dy;
            if (xx >= 0 && yy >= 0 && xx < width && yy < height)
                for (int c = 0; c < 3; c++) s[c] += unit[4 * (yy * width + xx) + c] / 9.0f;
        }
    float n = sqrtf(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
    bool ok = n > 1e-12f;
    for (int c = 0; c < 3; c++) nbar[4 * i + c] = ok ? s[c] / n : 0.0f;
    nbar[4 * i + 3] = ok ? n : 0.0f;
}

__device__ __forceinline__ void through_normalise(const float* g, const float* u, float norm, float* out) {
    if (norm == 0.0f) {
        out[0] = out[1] = out[2] = 0.0f;
        return;
    }
    float d = g[0] * u[0] + g[1] * u[1] + g[2] * u[2];
    for (int c = 0; c < 3; c++) out[c] = (g[c] - d * u[c]) / norm;
}

// L_geo's terms: adds its direct gradient into g_unit and writes the gradient on the pooled
// mean m (g_m); `s` = weight / sum of weights.
extern "C" __global__ void geo_terms(int p, const float* unit, const float* nbar, const float* wg, float s,
                                     float inv_wsum, float* g_unit, float* g_m, unsigned long long* acc) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    float l = 0.0f;
    if (i < p) {
        float gm[3] = {0.0f, 0.0f, 0.0f};
        float wi = wg[i];
        const float* u = unit + 4 * i;
        const float* nb = nbar + 4 * i;
        if (wi > 0.0f && u[3] != 0.0f) {
            l = wi * (1.0f - (u[0] * nb[0] + u[1] * nb[1] + u[2] * nb[2])) * inv_wsum;
            for (int c = 0; c < 3; c++) g_unit[3 * i + c] -= s * wi * nb[c];
            float g_nbar[3] = {-s * wi * u[0], -s * wi * u[1], -s * wi * u[2]};
            through_normalise(g_nbar, nb, nb[3], gm);
        }
        for (int c = 0; c < 3; c++) g_m[3 * i + c] = gm[c];
    }
    warp_add(acc, 5, l);
}

// The pool's adjoint (when `geo`), then back through the normalisation to the rendered normal.
extern "C" __global__ void normal_finish(int width, int height, int geo, const float* unit, const float* g_unit,
                                         const float* g_m, float* up_normal) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= width * height) return;
    float g[3] = {g_unit[3 * i], g_unit[3 * i + 1], g_unit[3 * i + 2]};
    if (geo) {
        int x = i % width, y = i / width;
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                int xx = x + dx, yy = y + dy;
                if (xx >= 0 && yy >= 0 && xx < width && yy < height)
                    for (int c = 0; c < 3; c++) g[c] += g_m[3 * (yy * width + xx) + c] / 9.0f;
            }
    }
    through_normalise(g, unit + 4 * i, unit[4 * i + 3], up_normal + 3 * i);
}
