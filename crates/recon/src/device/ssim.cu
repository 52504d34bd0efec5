// SSIM on the device (recon::ssim, in f32), one 16x16 tile of the image a block. Compiled after
// kernels.cu (its warp_add). The window is separable (11 taps, zero padding): a block loads its
// tile and a halo of RADIUS pixels into shared memory, blurs each row of that region across the
// tile's 16 columns, then each pixel blurs its column. The two passes add the same products in
// the same order as a horizontal then a vertical pass over whole images, so the results are
// those of blurring maps in global memory, without writing and re-reading the 15 input maps and
// the intermediate images (at 1920x1280 the five whole-image kernels took 1.7 ms an iteration).

#define RADIUS 5
#define SSIM_C1 0.0001f
#define SSIM_C2 0.0009f
#define ST 16                 // the tile's edge
#define SH (ST + 2 * RADIUS)  // the tile and its halo

struct Win {
    float w[2 * RADIUS + 1];
};

// Blurs map `m` of `hsrc` (halo-sized rows, value(hy, hx)) across the tile's columns into
// hb[m][hy][tx]: the horizontal pass. Taps outside the image are skipped, as zero padding.
template <int M, typename F>
__device__ __forceinline__ void rows_pass(const Win& win, int x0, int width, float (*hb)[SH][ST], F value) {
    for (int a = threadIdx.x; a < SH * ST; a += blockDim.x) {
        int hy = a / ST, tx = a % ST;
        float s[M];
#pragma unroll
        for (int m = 0; m < M; m++) s[m] = 0.0f;
        for (int k = 0; k <= 2 * RADIUS; k++) {
            int xx = x0 + tx + k - RADIUS;
            if (xx < 0 || xx >= width) continue;
            float v[M];
            value(hy, tx + k, v);
#pragma unroll
            for (int m = 0; m < M; m++) s[m] += win.w[k] * v[m];
        }
#pragma unroll
        for (int m = 0; m < M; m++) hb[m][hy][tx] = s[m];
    }
}

// The vertical pass at pixel (tx, ty) of the tile whose top row is y0: map m's blurred value.
__device__ __forceinline__ float column_pass(const Win& win, int y0, int height, const float (*hb)[ST], int tx, int ty) {
    float s = 0.0f;
    for (int k = 0; k <= 2 * RADIUS; k++) {
        int yy = y0 + ty + k - RADIUS;
        if (yy >= 0 && yy < height) s += win.w[k] * hb[ty + k][tx];
    }
    return s;
}

// recon::ssim::ssim_channel's map and its three partial derivatives for every channel (9 maps
// into `terms`: per channel d_mu, d_xx, d_xy, each divided by the pixel count), from the
// composite `out` and the target (3 channels, interleaved); the map's sum into acc[2]. `skeep`
// (may be null: every window) weighs each window centre (recon::ssim::ssim_channel_with's `keep`:
// 0 for a window that reaches a pixel left out of training).
// Grid: one block of 256 threads per tile.
extern "C" __global__ void __launch_bounds__(256) ssim_forward(int width, int height, Win win, const float* out,
                                                               const float* target, const float* skeep, float* terms,
                                                               unsigned long long* acc) {
    __shared__ float xs[3][SH][SH], ys[3][SH][SH];
    __shared__ float hb[5][SH][ST];
    int x0 = blockIdx.x * ST, y0 = blockIdx.y * ST;
    int tx = threadIdx.x % ST, ty = threadIdx.x / ST;
    int px = x0 + tx, py = y0 + ty;
    bool inside = px < width && py < height;
    size_t p = (size_t)width * height;
    for (int a = threadIdx.x; a < SH * SH; a += blockDim.x) {
        int hy = a / SH, hx = a % SH, gx = x0 + hx - RADIUS, gy = y0 + hy - RADIUS;
        bool in = gx >= 0 && gx < width && gy >= 0 && gy < height;
        size_t i = in ? (size_t)gy * width + gx : 0;
        for (int c = 0; c < 3; c++) {
            xs[c][hy][hx] = in ? out[3 * i + c] : 0.0f;
            ys[c][hy][hx] = in ? target[3 * i + c] : 0.0f;
        }
    }
    float inv_n = 1.0f / (float)p, ssum = 0.0f;
    size_t i = (size_t)py * width + px;
    for (int c = 0; c < 3; c++) {
        __syncthreads();
        rows_pass<5>(win, x0, width, hb, [&](int hy, int hx, float* v) {
            float x = xs[c][hy][hx], y = ys[c][hy][hx];
            v[0] = x;
            v[1] = y;
            v[2] = x * x;
            v[3] = y * y;
            v[4] = x * y;
        });
        __syncthreads();
        if (!inside) continue;
        float mx = column_pass(win, y0, height, hb[0], tx, ty), my = column_pass(win, y0, height, hb[1], tx, ty);
        float exx = column_pass(win, y0, height, hb[2], tx, ty), eyy = column_pass(win, y0, height, hb[3], tx, ty);
        float exy = column_pass(win, y0, height, hb[4], tx, ty);
        float a1 = 2.0f * mx * my + SSIM_C1;
        float a2 = 2.0f * (exy - mx * my) + SSIM_C2;
        float b1 = mx * mx + my * my + SSIM_C1;
        float b2 = (exx - mx * mx) + (eyy - my * my) + SSIM_C2;
        float s = a1 * a2 / (b1 * b2);
        float kw = skeep ? skeep[i] : 1.0f, kn = kw * inv_n;
        ssum += kw * s;
        float* t = terms + (size_t)c * 3 * p;
        t[i] = kn * (2.0f * my * (a2 - a1) / (b1 * b2) - 2.0f * mx * s * (1.0f / b1 - 1.0f / b2));
        t[p + i] = kn * (-s / b2);
        t[2 * p + i] = kn * (2.0f * a1 / (b1 * b2));
    }
    warp_add(acc, 2, ssum);
}

// The same window over `maps` (map blockIdx.z of width x height) into `dst`: the blur of the
// SSIM terms on the way back. Grid: one block of 256 threads per tile and map.
extern "C" __global__ void __launch_bounds__(256) blur_maps(int width, int height, Win win, const float* maps,
                                                            float* dst) {
    __shared__ float ms[SH][SH];
    __shared__ float hb[1][SH][ST];
    int x0 = blockIdx.x * ST, y0 = blockIdx.y * ST;
    int tx = threadIdx.x % ST, ty = threadIdx.x / ST;
    size_t p = (size_t)width * height;
    const float* src = maps + blockIdx.z * p;
    for (int a = threadIdx.x; a < SH * SH; a += blockDim.x) {
        int hy = a / SH, hx = a % SH, gx = x0 + hx - RADIUS, gy = y0 + hy - RADIUS;
        bool in = gx >= 0 && gx < width && gy >= 0 && gy < height;
        ms[hy][hx] = in ? src[(size_t)gy * width + gx] : 0.0f;
    }
    __syncthreads();
    rows_pass<1>(win, x0, width, hb, [&](int hy, int hx, float* v) { v[0] = ms[hy][hx]; });
    __syncthreads();
    int px = x0 + tx, py = y0 + ty;
    if (px < width && py < height) dst[blockIdx.z * p + (size_t)py * width + px] = column_pass(win, y0, height, hb[0], tx, ty);
}
