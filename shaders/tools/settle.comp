#version 460
// The device's settling load (src/renderer/settle.rs): arithmetic with no memory traffic,
// dispatched back to back before a timed measurement so that a GPU that idled down its
// clocks between renders (an H200 drops from 1980 to 345 MHz within a second of idling)
// is at its working clocks when the first timed frame starts. Nothing reads its result:
// the one store, behind a comparison no input makes true, keeps the loop from being
// optimised away.

layout(local_size_x = 64) in;

layout(push_constant) uniform PushBlock {
    uint iterations;  // FMAs per invocation (under lavapipe's 65 535 loop iterations)
    uint pad0;
    uint pad1;
    uint pad2;
} u_push;

layout(std430, set = 0, binding = 0) writeonly buffer SinkBlock {
    float sink[];
};

void main() {
    float x = float(gl_GlobalInvocationID.x) * 1.0e-7;
    float y = 1.0 - x;
    for (uint i = 0u; i < u_push.iterations; ++i) {
        x = fma(x, 0.9999999, 1.0e-7);
        y = fma(y, 1.0000001, -1.0e-7);
    }
    if (x == y && x == 12345.0) {
        sink[0] = x;
    }
}
