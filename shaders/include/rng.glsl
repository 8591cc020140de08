// Random numbers: a PCG hash to seed, a PCG (LCG + output permutation) stream.
#ifndef NIMBUS_RNG_GLSL
#define NIMBUS_RNG_GLSL

uint pcg_hash(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// Seed a stream for one pixel, frame and sample from independent hashes of each.
uint rng_init(uvec2 pixel, uint frame, uint sample_index, uint seed) {
    return pcg_hash(pixel.x ^ pcg_hash(pixel.y ^ pcg_hash(frame ^ pcg_hash(sample_index ^ pcg_hash(seed)))));
}

// Uniform float in [0, 1): the top 24 bits of the next PCG output.
float rng_next(inout uint state) {
    state = state * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    word = (word >> 22u) ^ word;
    return float(word >> 8u) * (1.0 / 16777216.0);
}

#endif
