// The per-Gaussian half of the backward pass (splat::chain, in f32): from one Gaussian's summed
// screen-space gradients (mean, conic, opacity, colour, depth, normal) to its parameters.
// Layout of a Gaussian's G2 row: mean 0..2, conic 2..5, opacity 5, colour 6..9, depth 9,
// normal 10..13 (output frame), features 13..13+NF.

// A warp's SH rows pass through shared memory: a Gaussian's coefficients (48 floats at degree 3)
// are its own 192-byte row, so a thread reading them from global memory made each warp
// instruction touch 32 cache lines: chain_kernel spent 87 % of its cycles waiting on those loads
// (ncu, 100k Gaussians: 197 us). A warp copies its lanes' rows in and out a row at a time, 32
// lanes on consecutive words; a row's stride in shared memory is odd, so a lane reading one
// coefficient of its own row meets a different bank from the other 31.
#define ROW_THREADS 128
#define ROW_STRIDE 49

// Gaussian i's gradients; `row` holds its SH coefficients on entry and their gradient on return.
// False, having written nothing, where the projection culls the Gaussian.
__device__ __forceinline__ bool chain_one(int i, const float* means, const float* log_scales, const float* rots,
                                          const float* logits, const Cam& cam, const Opts& o, const float* a,
                                          float* row, float* g_means, float* g_log_scales, float* g_rots,
                                          float* g_logits, float* g_mean2d) {
    int kc = (o.sh_degree + 1) * (o.sh_degree + 1);
    Proj pr;
    Frame f;
    if (!project_one(i, means, log_scales, rots, logits, row, cam, o, pr, f)) return false;
    float g_p[3] = {0.0f, 0.0f, 0.0f}, g_m[3] = {0.0f, 0.0f, 0.0f};
    // Colour -> SH coefficients and view direction (the coefficients read before the row is
    // overwritten with their gradient).
    float wk[16];
#pragma unroll
    for (int k = 0; k < 16; k++) wk[k] = 0.0f;
    for (int ch = 0; ch < 3; ch++) {
        float ac = a[6 + ch];
        if (ac == 0.0f) continue;
        for (int k = 0; k < kc; k++) wk[k] += ac * row[k * 3 + ch];
    }
    for (int ch = 0; ch < 3; ch++) {
        float ac = a[6 + ch];
        for (int k = 0; k < kc; k++) row[k * 3 + ch] = ac == 0.0f ? 0.0f : ac * f.basis[k];
    }
    const float* W = cam.r;
    float x = f.p[0], y = f.p[1], z = f.p[2];
    float g_dir[3] = {0.0f, 0.0f, 0.0f};
    sh_basis_grad_dot(o.sh_degree, f.dir, wk, g_dir);
    float dd = f.dir[0] * g_dir[0] + f.dir[1] * g_dir[1] + f.dir[2] * g_dir[2];
    for (int c = 0; c < 3; c++) g_m[c] += (g_dir[c] - f.dir[c] * dd) / f.dist;
    // Opacity -> logit and the antialiasing factor.
    g_logits[i] = a[5] * f.aa * f.sig * (1.0f - f.sig);
    float gc[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    if (o.antialiased && f.aa > 0.0f) {
        float g_aa = a[5] * f.sig;
        const float* c0 = f.cov0;
        const float* c = f.cov;
        float det0 = c0[0] * c0[3] - c0[1] * c0[2];
        float det = c[0] * c[3] - c[1] * c[2];
        float k0 = g_aa * f.aa / (2.0f * det0), k1 = -g_aa * f.aa / (2.0f * det);
        gc[0] += k0 * c0[3] + k1 * c[3];
        gc[3] += k0 * c0[0] + k1 * c[0];
        gc[1] += -k0 * c0[2] - k1 * c[2];
        gc[2] += -k0 * c0[1] - k1 * c[1];
    }
    // Conic -> covariance: dSigma = -K G_K K.
    {
        float K[4] = {pr.conic[0], pr.conic[1], pr.conic[1], pr.conic[2]};
        float G[4] = {a[2], a[3] * 0.5f, a[3] * 0.5f, a[4]};
        float KG[4], P[4];
        for (int r = 0; r < 2; r++)
            for (int c = 0; c < 2; c++) KG[2 * r + c] = K[2 * r] * G[c] + K[2 * r + 1] * G[2 + c];
        for (int r = 0; r < 2; r++)
            for (int c = 0; c < 2; c++) P[2 * r + c] = KG[2 * r] * K[c] + KG[2 * r + 1] * K[2 + c];
        for (int k = 0; k < 4; k++) gc[k] -= P[k];
    }
    const float* T = f.T;
    float g_sig3[9];
#pragma unroll
    for (int r = 0; r < 3; r++)
#pragma unroll
        for (int c = 0; c < 3; c++) {
            float acc = 0.0f;
#pragma unroll
            for (int u = 0; u < 2; u++)
#pragma unroll
                for (int v = 0; v < 2; v++) acc += T[3 * u + r] * gc[2 * u + v] * T[3 * v + c];
            g_sig3[3 * r + c] = acc;
        }
    float gsym[4] = {gc[0] * 2.0f, gc[1] + gc[2], gc[1] + gc[2], gc[3] * 2.0f};
    float g_t[6];
#pragma unroll
    for (int r = 0; r < 2; r++)
#pragma unroll
        for (int c = 0; c < 3; c++) {
            float acc = 0.0f;
#pragma unroll
            for (int u = 0; u < 2; u++)
#pragma unroll
                for (int v = 0; v < 3; v++) acc += gsym[2 * r + u] * T[3 * u + v] * f.sig3[3 * v + c];
            g_t[3 * r + c] = acc;
        }
    float g_j[6];
#pragma unroll
    for (int r = 0; r < 2; r++)
#pragma unroll
        for (int c = 0; c < 3; c++)
            g_j[3 * r + c] = g_t[3 * r] * W[3 * c] + g_t[3 * r + 1] * W[3 * c + 1] + g_t[3 * r + 2] * W[3 * c + 2];
    float fx = cam.fx, fy = cam.fy, z2 = z * z;
    float ux = f.clamped[0] ? 0.0f : x / z, uy = f.clamped[1] ? 0.0f : y / z;
    float txz = fminf(fmaxf(x / z, -1.3f * cam.cx / fx), 1.3f * ((float)cam.width - cam.cx) / fx);
    float tyz = fminf(fmaxf(y / z, -1.3f * cam.cy / fy), 1.3f * ((float)cam.height - cam.cy) / fy);
    g_p[2] += g_j[0] * -fx / z2 + g_j[4] * -fy / z2;
    g_p[2] += g_j[2] * fx * txz / z2 + g_j[5] * fy * tyz / z2;
    if (!f.clamped[0]) {
        g_p[0] += g_j[2] * -fx / z2;
        g_p[2] += g_j[2] * -fx / z * (-ux / z);
    }
    if (!f.clamped[1]) {
        g_p[1] += g_j[5] * -fy / z2;
        g_p[2] += g_j[5] * -fy / z * (-uy / z);
    }
    g_p[0] += a[0] * fx / z;
    g_p[1] += a[1] * fy / z;
    g_p[2] += a[0] * -fx * x / z2 + a[1] * -fy * y / z2 + a[9];
    // Normal: the output-frame gradient back to camera axes, then n_cam = +-W R[:, kmin].
    float an[3];
    for (int c = 0; c < 3; c++)
        an[c] = o.normals_world ? W[3 * c] * a[10] + W[3 * c + 1] * a[11] + W[3 * c + 2] * a[12] : a[10 + c];
    float sign = f.flipped ? -1.0f : 1.0f;
    float g_r[9];
#pragma unroll
    for (int k = 0; k < 9; k++) g_r[k] = 0.0f;
#pragma unroll
    for (int r = 0; r < 3; r++) {
        float v = sign * (W[r] * an[0] + W[3 + r] * an[1] + W[6 + r] * an[2]);
#pragma unroll
        for (int k = 0; k < 3; k++)
            if (k == f.kmin) g_r[3 * r + k] += v;
    }
#pragma unroll
    for (int c = 0; c < 3; c++) g_m[c] += W[c] * g_p[0] + W[3 + c] * g_p[1] + W[6 + c] * g_p[2];
    // Sigma3 = M M^T, M = R diag(s): dL/dM = (G + G^T) M.
#pragma unroll
    for (int k = 0; k < 3; k++) {
        float gs = 0.0f;
#pragma unroll
        for (int r = 0; r < 3; r++) {
            float gmrk = 0.0f;
#pragma unroll
            for (int c = 0; c < 3; c++) gmrk += (g_sig3[3 * r + c] + g_sig3[3 * c + r]) * f.R[3 * c + k] * f.s[k];
            gs += gmrk * f.R[3 * r + k];
            g_r[3 * r + k] += gmrk * f.s[k];
        }
        g_log_scales[3 * i + k] = gs * f.s[k];
    }
    // R(q) with q normalised.
    float q[4] = {rots[4 * i], rots[4 * i + 1], rots[4 * i + 2], rots[4 * i + 3]};
    float nq = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (nq > 0.0f) {
        float w = q[0] / nq, qx = q[1] / nq, qy = q[2] / nq, qz = q[3] / nq;
        const float* g = g_r;
        float gw = 2.0f * (-qz * g[1] + qy * g[2] + qz * g[3] - qx * g[5] - qy * g[6] + qx * g[7]);
        float gx = 2.0f * (qy * g[1] + qz * g[2] + qy * g[3] - 2.0f * qx * g[4] - w * g[5] + qz * g[6] + w * g[7] -
                           2.0f * qx * g[8]);
        float gy = 2.0f * (-2.0f * qy * g[0] + qx * g[1] + w * g[2] + qx * g[3] + qz * g[5] - w * g[6] + qz * g[7] -
                           2.0f * qy * g[8]);
        float gz = 2.0f * (-2.0f * qz * g[0] - w * g[1] + qx * g[2] + w * g[3] - 2.0f * qz * g[4] + qy * g[5] +
                           qx * g[6] + qy * g[7]);
        float gq[4] = {gw, gx, gy, gz}, qh[4] = {w, qx, qy, qz};
        float dot = qh[0] * gq[0] + qh[1] * gq[1] + qh[2] * gq[2] + qh[3] * gq[3];
        for (int c = 0; c < 4; c++) g_rots[4 * i + c] = (gq[c] - qh[c] * dot) / nq;
    }
    for (int c = 0; c < 3; c++) g_means[3 * i + c] = g_m[c];
    g_mean2d[i] = sqrtf(a[0] * a[0] + a[1] * a[1]);
    return true;
}

// Copies the rows of the warp's lanes set in `lanes` from `src` to `dst` (row r at r times each
// side's stride: global rows are kc3 floats apart, shared ones ROW_STRIDE), a row per step, 32
// lanes on consecutive words.
__device__ __forceinline__ void copy_rows(unsigned lanes, int lane, int kc3, const float* src, int src_stride,
                                          float* dst, int dst_stride) {
    for (; lanes; lanes &= lanes - 1) {
        int r = __ffs(lanes) - 1;
        for (int e = lane; e < kc3; e += 32) dst[r * dst_stride + e] = src[r * src_stride + e];
    }
    __syncwarp();
}

// g_sh is cleared before: only the rows of Gaussians with a gradient are written. Gaussian i's
// screen-space sums come from the backward's fixed-point rows `g2q` (fixed.cu), with the scale's
// upstream max `fix_max` and the forward's projections `proj` (the conic's unit).
extern "C" __global__ void __launch_bounds__(ROW_THREADS) chain_kernel(
    int n, const float* means, const float* log_scales, const float* rots, const float* logits, const float* sh,
    Cam cam, Opts o, const int* valid, const unsigned long long* g2q, const Proj* proj, const unsigned* fix_max,
    float* g_means, float* g_log_scales, float* g_rots, float* g_logits, float* g_sh, float* g_feat,
    float* g_mean2d) {
    __shared__ float rows[ROW_THREADS * ROW_STRIDE];
    int i = blockIdx.x * ROW_THREADS + threadIdx.x, lane = threadIdx.x & 31;
    int kc3 = 3 * (o.sh_degree + 1) * (o.sh_degree + 1);
    size_t first = (size_t)(i - lane) * kc3;
    float* warp_rows = rows + (threadIdx.x - lane) * ROW_STRIDE;
    unsigned max_bits = *fix_max;
    float a[13];
    bool active = false;
    if (i < n) {
        float scale = fix_scale(max_bits);
        bool nan = max_bits > 0x7f7fffffu;
        for (int c = 0; c < NF; c++)
            g_feat[(size_t)i * NF + c] = fixed_value((long long)g2q[(size_t)i * G2N + 13 + c], 13 + c, scale, 1.0f, nan);
        active = valid[i] && fixed_row(i, g2q, proj, max_bits, a);
    }
    copy_rows(__ballot_sync(0xffffffffu, active), lane, kc3, sh + first, kc3, warp_rows, ROW_STRIDE);
    bool wrote = active && chain_one(i, means, log_scales, rots, logits, cam, o, a, rows + threadIdx.x * ROW_STRIDE,
                                     g_means, g_log_scales, g_rots, g_logits, g_mean2d);
    __syncwarp();
    copy_rows(__ballot_sync(0xffffffffu, wrote), lane, kc3, warp_rows, ROW_STRIDE, g_sh + first, kc3);
}
