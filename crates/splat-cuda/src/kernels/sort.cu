// Device prefix sums and a stable LSD radix sort of (u64 key, u32 value) pairs, 8 bits a pass.
// Scan: 1024 values a block (256 threads x 4), block totals scanned recursively by the host.
// Sort pass: per-block digit histograms (digit-major, so one exclusive scan of them gives every
// block's output offset per digit), then a stable scatter that ranks equal digits within a warp
// with __match_any_sync and across the block's warps through shared counters.

#define SCAN_ITEMS 4
#define SCAN_BLOCK (256 * SCAN_ITEMS)

// Exclusive scan of `in` into `out` per block of SCAN_BLOCK values; block totals into `sums`.
extern "C" __global__ void scan_blocks(unsigned n, const unsigned* in, unsigned* out, unsigned* sums) {
    __shared__ unsigned warp_tot[8];
    unsigned base = blockIdx.x * SCAN_BLOCK + threadIdx.x * SCAN_ITEMS;
    unsigned v[SCAN_ITEMS], local = 0;
#pragma unroll
    for (int k = 0; k < SCAN_ITEMS; k++) {
        v[k] = base + k < n ? in[base + k] : 0u;
        local += v[k];
    }
    int lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
    unsigned incl = local;
    for (int off = 1; off < 32; off <<= 1) {
        unsigned y = __shfl_up_sync(0xffffffffu, incl, off);
        if (lane >= off) incl += y;
    }
    if (lane == 31) warp_tot[warp] = incl;
    __syncthreads();
    unsigned before = 0, total = 0;
    for (int w = 0; w < 8; w++) {
        if (w < warp) before += warp_tot[w];
        total += warp_tot[w];
    }
    unsigned run = before + incl - local;
#pragma unroll
    for (int k = 0; k < SCAN_ITEMS; k++) {
        if (base + k < n) out[base + k] = run;
        run += v[k];
    }
    if (threadIdx.x == 0) sums[blockIdx.x] = total;
}

// Adds each block's scanned total offset to its values.
extern "C" __global__ void scan_add(unsigned n, unsigned* out, const unsigned* offs) {
    unsigned i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i < n) out[i] += offs[i / SCAN_BLOCK];
}

// out[0] = offsets[n-1] + counts[n-1] (the total of an exclusive scan).
extern "C" __global__ void scan_total(unsigned n, const unsigned* offsets, const unsigned* counts, unsigned* total) {
    total[0] = n == 0 ? 0u : offsets[n - 1] + counts[n - 1];
}

#define SORT_ITEMS 16
#define SORT_CHUNK (256 * SORT_ITEMS)

extern "C" __global__ void radix_hist(unsigned n, const unsigned long long* keys, int shift, unsigned nblocks,
                                      unsigned* hist) {
    __shared__ unsigned h[256];
    h[threadIdx.x] = 0;
    __syncthreads();
    unsigned base = blockIdx.x * SORT_CHUNK;
    for (int k = 0; k < SORT_ITEMS; k++) {
        unsigned i = base + k * 256 + threadIdx.x;
        if (i < n) atomicAdd(&h[(unsigned)(keys[i] >> shift) & 255u], 1u);
    }
    __syncthreads();
    hist[threadIdx.x * nblocks + blockIdx.x] = h[threadIdx.x];
}

extern "C" __global__ void radix_scatter(unsigned n, const unsigned long long* keys, const unsigned* vals,
                                         unsigned long long* keys_out, unsigned* vals_out, int shift,
                                         unsigned nblocks, const unsigned* offsets) {
    __shared__ unsigned running[256];
    __shared__ unsigned wc[8][256];
    int lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
    running[threadIdx.x] = offsets[threadIdx.x * nblocks + blockIdx.x];
    for (int w = 0; w < 8; w++) wc[w][threadIdx.x] = 0;
    __syncthreads();
    unsigned base = blockIdx.x * SORT_CHUNK;
    unsigned lt = (1u << lane) - 1u;
    for (int k = 0; k < SORT_ITEMS; k++) {
        unsigned i = base + k * 256 + threadIdx.x;
        bool ok = i < n;
        unsigned long long key = ok ? keys[i] : 0ull;
        unsigned d = ok ? (unsigned)(key >> shift) & 255u : 256u + lane;  // unique dummies never match
        unsigned peers = __match_any_sync(0xffffffffu, d);
        unsigned rank = __popc(peers & lt);
        if (ok && rank == 0) wc[warp][d] = __popc(peers);
        __syncthreads();
        if (ok) {
            unsigned pos = running[d] + rank;
            for (int w = 0; w < warp; w++) pos += wc[w][d];
            keys_out[pos] = key;
            vals_out[pos] = vals[i];
        }
        __syncthreads();
        unsigned add = 0;
        for (int w = 0; w < 8; w++) {
            add += wc[w][threadIdx.x];
            wc[w][threadIdx.x] = 0;
        }
        running[threadIdx.x] += add;
        __syncthreads();
    }
}
