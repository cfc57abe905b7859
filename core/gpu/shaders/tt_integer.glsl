// terratheme exact integer arithmetic for GLSL 3.30 (32-bit int and uint; docs/gpu.md).
//
// Included by tt_blend.glsl. GLSL 3.30 has no 64-bit integers and its
// integer division is slow on software rasterisers, so every exact quotient
// here is a float estimate followed by one exact integer correction.
// Unsigned multiplication and addition keep the low 32 bits of their result
// (GLSL 1.30 and later), which the correction relies on: the remainder it
// tests is small even when the numerator needs more than 32 bits.
//
// Functions:
//   tt_divmod(a, b, 1/b)   floor(a / b) and a - b*floor(a / b), b > 0, |a| < 2^24
//   tt_quotient(a, b, e)   floor(A / b) for A >= 0 given a = A mod 2^32, b <= 2^30
//                          and a float estimate e within 1 of A / b
//   tt_quotient3           the same per component

// floor(a / b) and a - b*floor(a / b): a float estimate from the reciprocal,
// then one exact integer correction (the estimate is within 1 below 2^24).
ivec2 tt_divmod(int a, int b, float inv_b) {
    int q = int(floor((float(a) + 0.5) * inv_b));
    int r = a - q * b;
    if (r < 0) { q -= 1; r += b; } else if (r >= b) { q += 1; r -= b; }
    return ivec2(q, r);
}

// floor(A / b). The estimate's floor q is within one of the quotient, so the
// true remainder A - q*b lies in [-b, 2b) and, with b <= 2^30, its low 32
// bits read as a signed integer are exactly it.
uint tt_quotient(uint a, uint b, float e) {
    uint q = uint(max(floor(e), 0.0));
    int r = int(a - q * b);
    if (r < 0) q -= 1u; else if (uint(r) >= b) q += 1u;
    return q;
}

uvec3 tt_quotient3(uvec3 a, uint b, vec3 e) {
    return uvec3(tt_quotient(a.x, b, e.x), tt_quotient(a.y, b, e.y), tt_quotient(a.z, b, e.z));
}
