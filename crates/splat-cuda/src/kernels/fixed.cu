// One seed, one result: the backward's per-Gaussian sums in fixed point (docs/cuda.md). Float
// atomics add the warps' partial sums in whatever order the warps arrive, and float addition is
// not associative, so two trainings of one seed drifted apart (PandaSet 002, 15k steps: 26.79
// and 27.16 dB held-out). Integer addition is associative: each partial sum is scaled by a power
// of two (exact), rounded to the nearest integer and added with a 64-bit integer atomic, so the
// total is the same bits whatever the order; the chain rule reads the totals back as floats
// (`fixed_row`).
// The unit. `upstream_max` finds the largest upstream |gradient| U of any pixel and channel (an
// order-free max); one unit is U * 2^-FIX_BITS (2.3e-10 U), so a warp's sum keeps 32 bits
// against the largest pixel's gradient (the parity tests allow 1e-3 of each array's largest
// gradient). A pixel adds at most about U per unit of colour, normal, feature or depth (metres)
// to a value, so a sum stays below the 2^31 U = 2.1e9 U where it could wrap even if a Gaussian
// covering a whole 1920x1280 frame got 800 U from every pixel. The conic's gradient is the one
// exception: a pixel adds up to 0.74 t U to it, t the Gaussian's covariance trace in pixels^2,
// so its sums are kept in units 2^e times larger (t in [2^(e-1), 2^e), from the projected conic,
// which the forward pass fixed).
// A NaN contribution, or a non-finite upstream, sets the max to NaN's bits: every dequantized
// gradient is then NaN, as the float sums would have carried it.
#define FIX_BITS 32
#define FIX_NAN 0x7fffffffu

// Non-negative floats order as their bits; NaN's bits lie above infinity's.
__device__ __forceinline__ unsigned abs_bits(float x) { return __float_as_uint(x) & 0x7fffffffu; }

// 2^(FIX_BITS - e) for the largest |upstream| m in [2^(e-1), 2^e); 1 where there is no gradient.
__device__ __forceinline__ float fix_scale(unsigned max_bits) {
    float m = __uint_as_float(max_bits);
    if (!(m > 0.0f) || !isfinite(m)) return 1.0f;
    int e;
    frexpf(m, &e);
    return ldexpf(1.0f, min(max(FIX_BITS - e, -100), 100));
}

// 2^-e for a Gaussian whose covariance trace t = tr / det (pixels^2, tr and det of its conic)
// is within a factor of two of 2^e: e is the difference of tr's and det's binary exponents, read
// from their bits (an IEEE division and frexp/ldexp here cost the backward 15 % of its time),
// within +-20 (so that with fix_scale's +-100 no product leaves float's range); 1 where the
// conic is not a valid one. Explicit roundings: no FMA contraction may make the backward's and
// the chain rule's units differ.
__device__ __forceinline__ float conic_unit(const float* conic) {
    float tr = __fadd_rn(conic[0], conic[2]);
    float det = __fsub_rn(__fmul_rn(conic[0], conic[2]), __fmul_rn(conic[1], conic[1]));
    int e = (int)(__float_as_uint(tr) >> 23) - (int)(__float_as_uint(det) >> 23);
    e = min(max(e, -20), 20);
    return (tr > 0.0f) & (det > 0.0f) ? __uint_as_float((unsigned)(127 - e) << 23) : 1.0f;
}

// The scale of value k of a Gaussian's G2 row (conic values 2..5 in the Gaussian's own unit).
__device__ __forceinline__ float value_scale(int k, float scale, const float* conic) {
    return k >= 2 && k < 5 ? scale * conic_unit(conic) : scale;
}

// Adds `v` (scaled by `scale`) to the fixed-point sum at `dst`; a NaN marks the pass.
__device__ __forceinline__ void add_fixed(unsigned long long* dst, float v, float scale, unsigned* fix_max) {
    if (isnan(v)) {
        atomicMax(fix_max, FIX_NAN);
        return;
    }
    long long q = __float2ll_rn(v * scale);
    if (q != 0) atomicAdd(dst, (unsigned long long)q);
}

// The largest |value| of the upstream gradients (p pixels: rgb 3p, alpha p, depth p, normal 3p,
// features nf * p), as bits, into `out` (zeroed before).
extern "C" __global__ void upstream_max(unsigned p, unsigned nf, const float* rgb, const float* alpha,
                                        const float* depth, const float* normal, const float* feat, unsigned* out) {
    unsigned m = 0;
    for (size_t i = blockIdx.x * (size_t)blockDim.x + threadIdx.x; i < p; i += (size_t)gridDim.x * blockDim.x) {
        m = max(m, max(abs_bits(alpha[i]), abs_bits(depth[i])));
        for (int c = 0; c < 3; c++) m = max(m, max(abs_bits(rgb[3 * i + c]), abs_bits(normal[3 * i + c])));
        for (unsigned c = 0; c < nf; c++) m = max(m, abs_bits(feat[i * nf + c]));
    }
    m = __reduce_max_sync(0xffffffffu, m);
    if ((threadIdx.x & 31) == 0 && m != 0) atomicMax(out, m);
}

// Gaussian i's fixed-point sum of value k (k >= 13: a feature channel) as a float, in the units
// the backward used (`scale` = fix_scale, `conic` = conic_unit of the forward's projection).
__device__ __forceinline__ float fixed_value(long long v, int k, float scale, float conic, bool nan) {
    return nan ? __uint_as_float(FIX_NAN) : __ll2float_rn(v) / (k >= 2 && k < 5 ? scale * conic : scale);
}

// Gaussian i's first 13 G2 values (mean, conic, opacity, colour, depth, normal) from the
// fixed-point sums `q` into a[13]: the chain rule reads them here, so no float copy of the sums
// goes through global memory. False where all are zero (and the pass had no NaN).
__device__ __forceinline__ bool fixed_row(int i, const unsigned long long* q, const Proj* proj, unsigned max_bits,
                                          float* a) {
    const unsigned long long* r = q + (size_t)i * G2N;
    float scale = fix_scale(max_bits), conic = conic_unit(proj[i].conic);
    bool nan = max_bits > 0x7f7fffffu, any = nan;
#pragma unroll
    for (int k = 0; k < 13; k++) {
        long long v = (long long)r[k];
        any = any || v != 0;
        a[k] = fixed_value(v, k, scale, conic, nan);
    }
    return any;
}
