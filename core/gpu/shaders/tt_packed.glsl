// terratheme packed index layer, read in the shader (docs/formats.md
// section 3; docs/gpu.md "Packed layers"), GLSL 3.30 library.
//
// The layer stays packed on the GPU: its random-access table (the uint32
// words of core.packing.lookup.build_table, PackedLayer.table) is one R32UI
// texture, and a texel is found as the CPU kernels find it (core.packing.lookup
// _find): its block's grid word, the local step along the curve inside the
// block, the block's (or its quarter's) span of runs, a binary search.
//
// Textures:
//   tt_packed  usampler2D R32UI, 2^TT_PACKED_ROW_BITS texels wide: table word
//              i at texel (i mod 2^TT_PACKED_ROW_BITS, i >> TT_PACKED_ROW_BITS)
// Defines:
//   TT_PACKED_ROW_BITS  log2 of the texture's width (default 12: 4096 words a row)
// Entry: uint tt_packed_index(ivec2 p), the palette index of texel p = (column,
// row), row 0 the top row; 256u outside the layer.

#ifndef TT_PACKED_ROW_BITS
#define TT_PACKED_ROW_BITS 12
#endif

uniform usampler2D tt_packed;

// Table word i.
uint tt_word(uint i) {
    return texelFetch(tt_packed, ivec2(int(i & ((1u << TT_PACKED_ROW_BITS) - 1u)),
                                       int(i >> TT_PACKED_ROW_BITS)), 0).r;
}

// Hilbert step of (x, y) (y up) on a 2^n square, starting in state s: the
// table's state machine (words 12..27 one level, 28..1051 four levels at once).
uint tt_hilbert_local(uint x, uint y, uint n, uint s) {
    uint d = 0u;
    uint level = n;
    // Leading levels one at a time until a multiple of four remain.
    while ((level & 3u) != 0u) {
        level -= 1u;
        uint e = tt_word(12u + s * 4u + ((x >> level) & 1u) * 2u + ((y >> level) & 1u));
        d = (d << 2) | (e >> 2);
        s = e & 3u;
    }
    // Then four levels per table word.
    while (level > 0u) {
        level -= 4u;
        uint e = tt_word(28u + s * 256u + ((x >> level) & 15u) * 16u + ((y >> level) & 15u));
        d = (d << 8) | (e >> 2);
        s = e & 3u;
    }
    return d;
}

// The low 16 bits of v spread to the even bits.
uint tt_spread(uint v) {
    v &= 0xFFFFu;
    v = (v | (v << 8)) & 0x00FF00FFu;
    v = (v | (v << 4)) & 0x0F0F0F0Fu;
    v = (v | (v << 2)) & 0x33333333u;
    return (v | (v << 1)) & 0x55555555u;
}

// Palette index of texel p (column, row from the top), 256u outside the layer.
uint tt_packed_index(ivec2 p) {
    uint width = tt_word(0u), height = tt_word(1u);
    if (p.x < 0 || p.y < 0 || uint(p.x) >= width || uint(p.y) >= height) return 256u;
    // Step 1: the grid word of the texel's block (grid rows from the bottom).
    uint x = uint(p.x), yup = height - 1u - uint(p.y);
    uint b = tt_word(4u);
    uint g = tt_word(tt_word(5u) + (yup >> b) * tt_word(9u) + (x >> b));
    if (g >= 0x80000000u) return g & 255u;
    // Step 2: the local step inside the block (Morton: bits interleaved, x even).
    uint mask = (1u << b) - 1u;
    uint lx = x & mask, ly = yup & mask;
    uint local = tt_word(3u) != 0u ? (tt_spread(lx) | (tt_spread(ly) << 1))
                                   : tt_hilbert_local(lx, ly, b, g & 3u);
    // Step 3: the runs to search, the block's or its quarter's.
    uint at = tt_word(6u) + (g >> 3);
    if ((g & 4u) != 0u) at += local >> (2u * b - 2u);
    uint lo = tt_word(at), hi = tt_word(at + 1u) & 0x7FFFFFFFu;
    // Step 4: the first run in [lo, hi) whose low step bits are >= local, else run hi.
    uint runs = tt_word(7u) + lo;
    uint key = local << 8;
    uint left = hi - lo;
    while (left > 1u) {
        uint span = left >> 1;
        if (tt_word(runs + span - 1u) < key) runs += span;
        left -= span;
    }
    if (left == 1u && tt_word(runs) < key) runs += 1u;
    return tt_word(runs) & 255u;
}
