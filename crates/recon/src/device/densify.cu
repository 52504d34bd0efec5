// Adaptive density control on the device. `densify_plan` is recon::densify_rule::row_code line for
// line (the same f64 arithmetic and the same counter-based normals), one byte per row; the host
// reads the codes back (one byte a row), applies "never prune a set to nothing", and computes where
// each kept row and child goes; `densify_copy` then moves every parameter and moment row there
// (children copy their parent's parameters and start with zero moments), `densify_split` writes the
// split children's means and scales, and `opacity_cap` is the opacity reset.

#define KEEP 1
#define CLONE_KEPT 2
#define SPLIT0_KEPT 4
#define SPLIT1_KEPT 8
#define CLONED 16
#define SPLIT 32
#define SPLIT_SHRINK 1.6

struct Rule {
    double threshold, clone_max_scale, prune_opacity, max_screen, max_world;
    double actor_box[3];
    double actor_sigma;
    unsigned long long seed;
    int grow, prune_big, has_box, box_only;
};

__device__ unsigned long long mix64(unsigned long long z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

__device__ double uniform01(unsigned long long seed, unsigned long long row, unsigned long long k) {
    unsigned long long h = mix64(seed ^ mix64(row * 16ULL + k + 0x9e3779b97f4a7c15ULL));
    return ((double)(h >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

__device__ double split_normal(unsigned long long seed, unsigned long long row, int child, int axis) {
    unsigned long long k = 2ULL * (3ULL * child + axis);
    double u1 = uniform01(seed, row, k), u2 = uniform01(seed, row, k + 1);
    return sqrt(-2.0 * log(u1)) * cos(2.0 * 3.141592653589793 * u2);
}

__device__ double max_scale(const double* ls) { return exp(fmax(fmax(ls[0], ls[1]), ls[2])); }

// splat::project::rotation: the rotation of a quaternion (w, x, y, z), normalised (identity if zero).
__device__ void rotation(const double* q4, double r[3][3]) {
    double w = q4[0], x = q4[1], y = q4[2], z = q4[3];
    double nq = sqrt(w * w + x * x + y * y + z * z);
    if (nq > 0.0) {
        w /= nq; x /= nq; y /= nq; z /= nq;
    } else {
        w = 1.0; x = 0.0; y = 0.0; z = 0.0;
    }
    r[0][0] = 1.0 - 2.0 * (y * y + z * z); r[0][1] = 2.0 * (x * y - w * z); r[0][2] = 2.0 * (x * z + w * y);
    r[1][0] = 2.0 * (x * y + w * z); r[1][1] = 1.0 - 2.0 * (x * x + z * z); r[1][2] = 2.0 * (y * z - w * x);
    r[2][0] = 2.0 * (x * z - w * y); r[2][1] = 2.0 * (y * z + w * x); r[2][2] = 1.0 - 2.0 * (x * x + y * y);
}

__device__ void split_child(const Rule& rule, unsigned long long row, int child, const double* mean,
                            const double* ls, const double* q4, double* m_out, double* ls_out) {
    double r[3][3];
    rotation(q4, r);
    double s[3], local[3];
    for (int a = 0; a < 3; a++) {
        s[a] = exp(ls[a]);
        local[a] = split_normal(rule.seed, row, child, a) * s[a];
    }
    for (int a = 0; a < 3; a++) {
        m_out[a] = mean[a] + r[a][0] * local[0] + r[a][1] * local[1] + r[a][2] * local[2];
        ls_out[a] = log(s[a] / SPLIT_SHRINK);
    }
}

// densify_rule::leaves_box: the row's `sigma`-sigma extent along a box axis leaves the padded box.
__device__ bool leaves_box(const double* b, double sigma, const double* mean, const double* ls, const double* q4) {
    double r[3][3];
    rotation(q4, r);
    double s[3] = {exp(ls[0]), exp(ls[1]), exp(ls[2])};
    for (int a = 0; a < 3; a++) {
        double e = sqrt((r[a][0] * s[0]) * (r[a][0] * s[0]) + (r[a][1] * s[1]) * (r[a][1] * s[1]) +
                        (r[a][2] * s[2]) * (r[a][2] * s[2]));
        if (fabs(mean[a]) + sigma * e > 0.55 * b[a]) return true;
    }
    return false;
}

// old_radius < 0: the row did not exist while the screen size was measured.
__device__ bool pruned(const Rule& rule, double logit, const double* mean, const double* ls, const double* q4,
                       double old_radius) {
    bool outside = rule.has_box != 0 && leaves_box(rule.actor_box, rule.actor_sigma, mean, ls, q4);
    if (rule.box_only != 0) return outside;
    double ms = max_scale(ls);
    bool transparent = 1.0 / (1.0 + exp(-logit)) < rule.prune_opacity;
    bool screen = old_radius >= 0.0 && rule.max_screen > 0.0 && old_radius > rule.max_screen;
    bool big = rule.prune_big != 0 && (screen || ms > rule.max_world);
    return transparent || big || outside;
}

__device__ void load_row(int r, const float* means, const float* log_scales, const float* rots, double* m,
                         double* ls, double* q) {
    for (int a = 0; a < 3; a++) {
        m[a] = means[3 * r + a];
        ls[a] = log_scales[3 * r + a];
    }
    for (int a = 0; a < 4; a++) q[a] = rots[4 * r + a];
}

// One thread per row of a set (rows src0..src0 + n); `row` in the hash is the row within its set.
extern "C" __global__ void densify_plan(int n, int src0, Rule rule, const float* means, const float* log_scales,
                                        const float* rots, const float* logits, const float* grad_sum,
                                        const unsigned* seen, const float* max_radius, unsigned char* codes) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    int r = src0 + i;
    double m[3], ls[3], q[4];
    load_row(r, means, log_scales, rots, m, ls, q);
    double logit = logits[r], radius = max_radius[r];
    double avg = seen[r] > 0 ? (double)grad_sum[r] / (double)seen[r] : 0.0;
    unsigned char code;
    if (!(rule.grow != 0 && rule.box_only == 0 && avg >= rule.threshold)) {
        code = pruned(rule, logit, m, ls, q, radius) ? 0 : KEEP;
    } else if (max_scale(ls) <= rule.clone_max_scale) {
        code = CLONED | (pruned(rule, logit, m, ls, q, radius) ? 0 : KEEP) | (pruned(rule, logit, m, ls, q, -1.0) ? 0 : CLONE_KEPT);
    } else {
        code = SPLIT;
        for (int child = 0; child < 2; child++) {
            double cm[3], cls[3];
            split_child(rule, (unsigned long long)i, child, m, ls, q, cm, cls);
            if (!pruned(rule, logit, cm, cls, q, -1.0)) code |= (child == 0 ? SPLIT0_KEPT : SPLIT1_KEPT);
        }
    }
    codes[r] = code;
}

// actor_space::ActorSpace::contains and prune_codes: a background row whose centre is in a marked
// voxel is pruned with any children (code 0). The same f64 arithmetic as the host.
struct Space {
    double origin[3];
    double voxel;
    int dims[3], pad;
};

extern "C" __global__ void space_prune(int n, int src0, Space sp, const unsigned* bits, const float* means,
                                       unsigned char* codes) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    int r = src0 + i;
    long long k[3];
    for (int a = 0; a < 3; a++) {
        double t = floor(((double)means[3 * r + a] - sp.origin[a]) / sp.voxel);
        if (!(t >= 0.0 && t < (double)sp.dims[a])) return;
        k[a] = (long long)t;
    }
    long long f = (k[0] * sp.dims[1] + k[1]) * sp.dims[2] + k[2];
    if ((bits[f >> 5] >> (f & 31)) & 1u) codes[r] = 0;
}

__device__ int kept_children(unsigned char c) {
    return ((c & CLONE_KEPT) != 0) + ((c & SPLIT0_KEPT) != 0) + ((c & SPLIT1_KEPT) != 0);
}

// One thread per value of `n` rows of `width` values: a kept row to dst_old[row], its kept
// children to dst_new[row].. (the parent's value, or zero for moments).
extern "C" __global__ void densify_copy(size_t n, int width, const unsigned char* codes, const unsigned* dst_old,
                                        const unsigned* dst_new, const float* src, float* dst, int zero_children) {
    size_t idx = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (idx >= n * (size_t)width) return;
    size_t row = idx / width;
    int c = (int)(idx - row * width);
    unsigned char code = codes[row];
    float v = src[idx];
    if (code & KEEP) dst[(size_t)dst_old[row] * width + c] = v;
    int kids = kept_children(code);
    for (int k = 0; k < kids; k++) dst[((size_t)dst_new[row] + k) * width + c] = zero_children ? 0.0f : v;
}

// The split children's means and log-scales (one thread per row of a set).
extern "C" __global__ void densify_split(int n, int src0, Rule rule, const unsigned char* codes,
                                         const unsigned* dst_new, const float* means, const float* log_scales,
                                         const float* rots, float* out_means, float* out_log_scales) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    int r = src0 + i;
    unsigned char code = codes[r];
    if (!(code & SPLIT)) return;
    double m[3], ls[3], q[4];
    load_row(r, means, log_scales, rots, m, ls, q);
    unsigned d = dst_new[r];
    for (int child = 0; child < 2; child++) {
        if (!(code & (child == 0 ? SPLIT0_KEPT : SPLIT1_KEPT))) continue;
        double cm[3], cls[3];
        split_child(rule, (unsigned long long)i, child, m, ls, q, cm, cls);
        for (int a = 0; a < 3; a++) {
            out_means[3 * (size_t)d + a] = (float)cm[a];
            out_log_scales[3 * (size_t)d + a] = (float)cls[a];
        }
        d++;
    }
}

// The opacity reset: every logit capped at `cap`.
extern "C" __global__ void opacity_cap(size_t n, float cap, float* logits) {
    size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i < n) logits[i] = fminf(logits[i], cap);
}
