#ifndef NIMBUS_CONSTANTS_GLSL
#define NIMBUS_CONSTANTS_GLSL

#define PI 3.14159265358979323846
#define INV_PI 0.31830988618379067154
#define INV_4PI 0.07957747154594766788
// A distance larger than any scene extent (scenes are validated to sizes <= 1e7 m);
// finite, so that 0 * FAR stays 0 instead of NaN.
#define FAR 1.0e30
// No index: no light, medium or shape.
#define NO_INDEX 0xffffffffu

#endif
