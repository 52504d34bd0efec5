// Device prefix sums and a stable LSD radix sort of (u32 key, u32 value) pairs, 8 bits a pass.
// Scan: 1024 values a block (256 threads x 4), block totals scanned recursively by the host.
// Sort pass: per-block digit histograms (digit-major, so one exclusive scan of them gives every
// block's output offset per digit), then a stable scatter. The scatter ranks equal digits within
// a warp with __match_any_sync and across the block's warps through shared counters, places its
// chunk in shared memory in digit order, and only then writes it out: consecutive threads write
// consecutive slots of a digit's run, so the stores coalesce (written straight to their buckets,
// every store of a pass touched its own line: 60 % of a 3M-Gaussian forward pass at 1080p).

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

extern "C" __global__ void radix_hist(unsigned n, const unsigned* keys, int shift, unsigned nblocks, unsigned* hist) {
    __shared__ unsigned h[256];
    h[threadIdx.x] = 0;
    __syncthreads();
    unsigned base = blockIdx.x * SORT_CHUNK;
    for (int k = 0; k < SORT_ITEMS; k++) {
        unsigned i = base + k * 256 + threadIdx.x;
        if (i < n) atomicAdd(&h[(keys[i] >> shift) & 255u], 1u);
    }
    __syncthreads();
    hist[threadIdx.x * nblocks + blockIdx.x] = h[threadIdx.x];
}

// One pass: `hist` holds every block's digit counts, `offsets` their digit-major exclusive scan.
extern "C" __global__ void radix_scatter(unsigned n, const unsigned* keys, const unsigned* vals, unsigned* keys_out,
                                         unsigned* vals_out, int shift, unsigned nblocks, const unsigned* hist,
                                         const unsigned* offsets) {
    __shared__ unsigned sk[SORT_CHUNK];
    __shared__ unsigned sv[SORT_CHUNK];
    __shared__ unsigned wc[8][256];
    __shared__ unsigned start[256];    // the chunk's first slot of each digit in sk/sv
    __shared__ unsigned out_from[256]; // the digit's output offset minus `start` (mod 2^32)
    __shared__ unsigned running[256];
    __shared__ unsigned warp_tot[8];
    int t = threadIdx.x, lane = t & 31, warp = t >> 5;
    // The chunk's digit starts: an exclusive scan of its 256 digit counts.
    unsigned c = hist[t * nblocks + blockIdx.x];
    unsigned incl = c;
    for (int off = 1; off < 32; off <<= 1) {
        unsigned y = __shfl_up_sync(0xffffffffu, incl, off);
        if (lane >= off) incl += y;
    }
    if (lane == 31) warp_tot[warp] = incl;
    for (int w = 0; w < 8; w++) wc[w][t] = 0;
    running[t] = 0;
    __syncthreads();
    unsigned before = 0;
    for (int w = 0; w < warp; w++) before += warp_tot[w];
    unsigned st = before + incl - c;
    start[t] = st;
    out_from[t] = offsets[t * nblocks + blockIdx.x] - st;
    __syncthreads();
    unsigned base = blockIdx.x * SORT_CHUNK;
    unsigned lt = (1u << lane) - 1u;
    for (int k = 0; k < SORT_ITEMS; k++) {
        unsigned i = base + k * 256 + t;
        bool ok = i < n;
        unsigned key = ok ? keys[i] : 0u;
        unsigned d = ok ? (key >> shift) & 255u : 256u + lane;  // unique dummies never match
        unsigned peers = __match_any_sync(0xffffffffu, d);
        unsigned rank = __popc(peers & lt);
        if (ok && rank == 0) wc[warp][d] = __popc(peers);
        __syncthreads();
        if (ok) {
            unsigned pos = start[d] + running[d] + rank;
            for (int w = 0; w < warp; w++) pos += wc[w][d];
            sk[pos] = key;
            sv[pos] = vals[i];
        }
        __syncthreads();
        unsigned add = 0;
        for (int w = 0; w < 8; w++) {
            add += wc[w][t];
            wc[w][t] = 0;
        }
        running[t] += add;
        __syncthreads();
    }
    unsigned count = n - base < SORT_CHUNK ? n - base : SORT_CHUNK;
    for (unsigned j = t; j < count; j += 256) {
        unsigned key = sk[j];
        unsigned o = out_from[(key >> shift) & 255u] + j;
        keys_out[o] = key;
        vals_out[o] = sv[j];
    }
}
