// Builds a BVH over a generated sphere and checks one ray against brute force.
#include <cstdio>

#include <raykit.hpp>
#include <raykit/scene/generate.hpp>

int main() {
    const raykit::Mesh mesh = raykit::make_icosphere(2);
    const raykit::Bvh bvh = raykit::build_bvh(mesh);
    const raykit::Ray ray{{0.01f, 0.02f, -5.0f}, 0.0f, {0.0f, 0.0f, 1.0f}, raykit::kInf};
    const raykit::Hit a = raykit::intersect_closest(mesh, bvh, ray);
    const raykit::Hit b = raykit::brute_force_closest(mesh, ray);
    std::printf("hit prim %u at t=%g (brute force %u)\n", a.prim, a.t, b.prim);
    return a.valid() && a.prim == b.prim && raykit::validate(bvh, raykit::primitive_refs(mesh).boxes).empty() ? 0 : 1;
}
