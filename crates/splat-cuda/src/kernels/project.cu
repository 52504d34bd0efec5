// Projection (EWA) and the per-Gaussian chain rule, in f32, mirroring splat::project and
// splat::chain line by line. Compiled by NVRTC with -DNF=<feature channels>.

#define ALPHA_MIN (1.0f / 255.0f)
#define ALPHA_MAX 0.99f
#define T_MIN 1e-4f
#define EPS2D 0.3f
#define TILE 16
#define G2N (13 + NF)

struct Cam {
    float r[9];      // camera_from_world rotation, row-major
    float t[3];
    float center[3]; // camera centre in the world
    float fx, fy, cx, cy, znear, zfar;
    int width, height;
};

struct Opts {
    float bg[3];
    int antialiased, smooth, normals_world, sh_degree, tiles_x, tiles_y;
};

// A Gaussian on screen: 16 floats.
struct Proj {
    float mean[2], conic[3], opacity, power_min, extent[2], depth, color[3], normal[3];
};

struct Frame {
    float p[3], R[9], s[3], sig3[9], T[6];
    int clamped[2];
    float cov0[4], cov[4];
    float sig, aa, dir[3], dist, basis[16];
    int kmin, flipped;
};

#define C0 0.28209479177387814f
#define C1 0.4886025119029199f

__device__ void sh_basis(int deg, const float* d, float* b) {
    float x = d[0], y = d[1], z = d[2];
#pragma unroll
    for (int k = 0; k < 16; k++) b[k] = 0.0f;
    b[0] = C0;
    if (deg >= 1) { b[1] = -C1 * y; b[2] = C1 * z; b[3] = -C1 * x; }
    if (deg >= 2) {
        float xx = x * x, yy = y * y, zz = z * z, xy = x * y, yz = y * z, xz = x * z;
        b[4] = 1.0925484305920792f * xy;
        b[5] = -1.0925484305920792f * yz;
        b[6] = 0.31539156525252005f * (2.0f * zz - xx - yy);
        b[7] = -1.0925484305920792f * xz;
        b[8] = 0.5462742152960396f * (xx - yy);
        if (deg >= 3) {
            b[9] = -0.5900435899266435f * y * (3.0f * xx - yy);
            b[10] = 2.890611442640554f * xy * z;
            b[11] = -0.4570457994644658f * y * (4.0f * zz - xx - yy);
            b[12] = 0.3731763325901154f * z * (2.0f * zz - 3.0f * xx - 3.0f * yy);
            b[13] = -0.4570457994644658f * x * (4.0f * zz - xx - yy);
            b[14] = 1.445305721320277f * z * (xx - yy);
            b[15] = -0.5900435899266435f * x * (xx - 3.0f * yy);
        }
    }
}

// d basis_k / d (x, y, z) times the colour gradient, summed: g_dir += sum_k w_k dY_k/dd.
__device__ void sh_basis_grad_dot(int deg, const float* d, const float* w, float* g) {
    float x = d[0], y = d[1], z = d[2];
    if (deg >= 1) { g[1] += -C1 * w[1]; g[2] += C1 * w[2]; g[0] += -C1 * w[3]; }
    if (deg >= 2) {
        const float a = 1.0925484305920792f, b5 = -1.0925484305920792f, c6 = 0.31539156525252005f,
                    d7 = -1.0925484305920792f, e8 = 0.5462742152960396f;
        g[0] += w[4] * a * y; g[1] += w[4] * a * x;
        g[1] += w[5] * b5 * z; g[2] += w[5] * b5 * y;
        g[0] += w[6] * c6 * -2.0f * x; g[1] += w[6] * c6 * -2.0f * y; g[2] += w[6] * c6 * 4.0f * z;
        g[0] += w[7] * d7 * z; g[2] += w[7] * d7 * x;
        g[0] += w[8] * e8 * 2.0f * x; g[1] += w[8] * e8 * -2.0f * y;
        if (deg >= 3) {
            float xx = x * x, yy = y * y, zz = z * z;
            const float k9 = -0.5900435899266435f, k10 = 2.890611442640554f, k11 = -0.4570457994644658f,
                        k12 = 0.3731763325901154f, k13 = -0.4570457994644658f, k14 = 1.445305721320277f,
                        k15 = -0.5900435899266435f;
            g[0] += w[9] * k9 * 6.0f * x * y; g[1] += w[9] * k9 * (3.0f * xx - 3.0f * yy);
            g[0] += w[10] * k10 * y * z; g[1] += w[10] * k10 * x * z; g[2] += w[10] * k10 * x * y;
            g[0] += w[11] * k11 * -2.0f * x * y; g[1] += w[11] * k11 * (4.0f * zz - xx - 3.0f * yy);
            g[2] += w[11] * k11 * 8.0f * y * z;
            g[0] += w[12] * k12 * -6.0f * x * z; g[1] += w[12] * k12 * -6.0f * y * z;
            g[2] += w[12] * k12 * (6.0f * zz - 3.0f * xx - 3.0f * yy);
            g[0] += w[13] * k13 * (4.0f * zz - 3.0f * xx - yy); g[1] += w[13] * k13 * -2.0f * x * y;
            g[2] += w[13] * k13 * 8.0f * x * z;
            g[0] += w[14] * k14 * 2.0f * x * z; g[1] += w[14] * k14 * -2.0f * y * z; g[2] += w[14] * k14 * (xx - yy);
            g[0] += w[15] * k15 * (3.0f * xx - 3.0f * yy); g[1] += w[15] * k15 * -6.0f * x * y;
        }
    }
}

__device__ __forceinline__ bool fin(float v) { return isfinite(v); }

// Projects Gaussian i, whose SH coefficients are `shi`; false if culled or degenerate (as
// splat::project::project_full).
__device__ bool project_one(int i, const float* means, const float* log_scales, const float* rots,
                            const float* logits, const float* shi, const Cam& cam, const Opts& o, Proj& out, Frame& f) {
    float m[3] = {means[3 * i], means[3 * i + 1], means[3 * i + 2]};
#pragma unroll
    for (int a = 0; a < 3; a++) f.p[a] = cam.r[3 * a] * m[0] + cam.r[3 * a + 1] * m[1] + cam.r[3 * a + 2] * m[2] + cam.t[a];
    if (!(f.p[2] > cam.znear && f.p[2] < cam.zfar) || !fin(f.p[0]) || !fin(f.p[1]) || !fin(f.p[2])) return false;
    float qw = rots[4 * i], qx = rots[4 * i + 1], qy = rots[4 * i + 2], qz = rots[4 * i + 3];
    float n = sqrtf(qw * qw + qx * qx + qy * qy + qz * qz);
    if (n > 0.0f) { qw /= n; qx /= n; qy /= n; qz /= n; } else { qw = 1.0f; qx = qy = qz = 0.0f; }
    float* R = f.R;
    R[0] = 1.0f - 2.0f * (qy * qy + qz * qz); R[1] = 2.0f * (qx * qy - qw * qz); R[2] = 2.0f * (qx * qz + qw * qy);
    R[3] = 2.0f * (qx * qy + qw * qz); R[4] = 1.0f - 2.0f * (qx * qx + qz * qz); R[5] = 2.0f * (qy * qz - qw * qx);
    R[6] = 2.0f * (qx * qz - qw * qy); R[7] = 2.0f * (qy * qz + qw * qx); R[8] = 1.0f - 2.0f * (qx * qx + qy * qy);
#pragma unroll
    for (int a = 0; a < 3; a++) {
        f.s[a] = expf(log_scales[3 * i + a]);
        if (!fin(f.s[a])) return false;
    }
#pragma unroll
    for (int a = 0; a < 3; a++)
#pragma unroll
        for (int b = 0; b < 3; b++) {
            float acc = 0.0f;
#pragma unroll
            for (int k = 0; k < 3; k++) acc += R[3 * a + k] * f.s[k] * f.s[k] * R[3 * b + k];
            f.sig3[3 * a + b] = acc;
        }
    float z = f.p[2], ux = f.p[0] / z, uy = f.p[1] / z;
    float cxn = fminf(fmaxf(ux, -1.3f * cam.cx / cam.fx), 1.3f * ((float)cam.width - cam.cx) / cam.fx);
    float cyn = fminf(fmaxf(uy, -1.3f * cam.cy / cam.fy), 1.3f * ((float)cam.height - cam.cy) / cam.fy);
    f.clamped[0] = cxn != ux;
    f.clamped[1] = cyn != uy;
    float tx = cxn * z, ty = cyn * z;
    float J[6] = {cam.fx / z, 0.0f, -cam.fx * tx / (z * z), 0.0f, cam.fy / z, -cam.fy * ty / (z * z)};
#pragma unroll
    for (int a = 0; a < 2; a++)
#pragma unroll
        for (int b = 0; b < 3; b++)
            f.T[3 * a + b] = J[3 * a] * cam.r[b] + J[3 * a + 1] * cam.r[3 + b] + J[3 * a + 2] * cam.r[6 + b];
    float cov[4];
#pragma unroll
    for (int a = 0; a < 2; a++)
#pragma unroll
        for (int b = 0; b < 2; b++) {
            float acc = 0.0f;
#pragma unroll
            for (int k = 0; k < 3; k++)
#pragma unroll
                for (int l = 0; l < 3; l++) acc += f.T[3 * a + k] * f.sig3[3 * k + l] * f.T[3 * b + l];
            cov[2 * a + b] = acc;
        }
    float det0 = cov[0] * cov[3] - cov[1] * cov[2];
#pragma unroll
    for (int k = 0; k < 4; k++) f.cov0[k] = cov[k];
    cov[0] += EPS2D;
    cov[3] += EPS2D;
    float det = cov[0] * cov[3] - cov[1] * cov[2];
    if (!(det > 0.0f) || !fin(det)) return false;
#pragma unroll
    for (int k = 0; k < 4; k++) f.cov[k] = cov[k];
    f.sig = 1.0f / (1.0f + expf(-logits[i]));
    f.aa = o.antialiased ? sqrtf(fmaxf(det0, 0.0f) / det) : 1.0f;
    float opacity = f.sig * f.aa;
    if (isnan(opacity) || (!o.smooth && opacity < ALPHA_MIN) || opacity <= 0.0f) return false;
    out.conic[0] = cov[3] / det;
    out.conic[1] = -cov[1] / det;
    out.conic[2] = cov[0] / det;
    float level = 2.0f * fmaxf(logf(255.0f * opacity), 0.0f);
    out.extent[0] = sqrtf(level * cov[0]);
    out.extent[1] = sqrtf(level * cov[3]);
    out.mean[0] = cam.fx * f.p[0] / z + cam.cx;
    out.mean[1] = cam.fy * f.p[1] / z + cam.cy;
    // Culled where the alpha >= 1/255 box misses the image (splat::project::on_screen; NaN fails).
    if (!o.smooth && !(out.mean[0] + out.extent[0] >= 0.0f && out.mean[0] - out.extent[0] < (float)cam.width &&
                       out.mean[1] + out.extent[1] >= 0.0f && out.mean[1] - out.extent[1] < (float)cam.height))
        return false;
    out.opacity = opacity;
    out.power_min = logf(ALPHA_MIN / opacity);
    out.depth = z;
    float d[3] = {m[0] - cam.center[0], m[1] - cam.center[1], m[2] - cam.center[2]};
    f.dist = fmaxf(sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), 1e-12f);
#pragma unroll
    for (int a = 0; a < 3; a++) f.dir[a] = d[a] / f.dist;
    sh_basis(o.sh_degree, f.dir, f.basis);
    int kc = (o.sh_degree + 1) * (o.sh_degree + 1);
#pragma unroll
    for (int ch = 0; ch < 3; ch++) {
        float acc = 0.0f;
        for (int k = 0; k < kc; k++) acc += f.basis[k] * shi[k * 3 + ch];
        out.color[ch] = 0.5f + acc;
    }
    int kmin = 0;
    if (f.s[1] < f.s[kmin]) kmin = 1;
    if (f.s[2] < f.s[kmin]) kmin = 2;
    f.kmin = kmin;
    float axis[3] = {R[kmin], R[3 + kmin], R[6 + kmin]};
    float nc[3];
#pragma unroll
    for (int a = 0; a < 3; a++) nc[a] = cam.r[3 * a] * axis[0] + cam.r[3 * a + 1] * axis[1] + cam.r[3 * a + 2] * axis[2];
    f.flipped = nc[0] * f.p[0] + nc[1] * f.p[1] + nc[2] * f.p[2] > 0.0f;
    if (f.flipped) { nc[0] = -nc[0]; nc[1] = -nc[1]; nc[2] = -nc[2]; }
    // The normal in the output frame (world on request: n_world = R^T n_cam).
#pragma unroll
    for (int a = 0; a < 3; a++)
        out.normal[a] = o.normals_world ? cam.r[a] * nc[0] + cam.r[3 + a] * nc[1] + cam.r[6 + a] * nc[2] : nc[a];
    bool ok = true;
#pragma unroll
    for (int a = 0; a < 3; a++) ok = ok && fin(out.conic[a]) && fin(out.color[a]) && fin(nc[a]);
    ok = ok && fin(out.mean[0]) && fin(out.mean[1]) && fin(out.extent[0]) && fin(out.extent[1]);
    return ok;
}
