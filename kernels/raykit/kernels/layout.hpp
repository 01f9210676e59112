// raykit/kernels/layout.hpp — OpenCL C definitions of every struct that
// crosses between host and device. The C++ twins and their static_asserts
// are in include/raykit/cl/layout.hpp; a probe kernel generated there checks
// sizes, alignments and offsets on the device at run time.
//
// Rule: 3-vectors are stored as three floats (float[3]) and read with vload3
// or element by element — never as float3, which is 16 bytes in OpenCL C but
// 12 in glm::vec3.
#pragma once

namespace raykit::kernels {

inline constexpr const char* kLayout = R"CLC(
/* Binary BVH node (raykit::Node), the top level's: leaf when count > 0 (instances
   top_ids[index..index+count)), else inner with children at index, index + 1. */
typedef struct __attribute__((aligned(32))) {
    float min[3];
    float max[3];
    uint index;
    uint count;
} rk_node;

/* Wide BVH node (raykit::WideNodeT<RK_WIDTH>, cl/device_tree.hpp): the RK_WIDTH children's
   boxes as planes[axis * 2 + (0 lo, 1 hi)][child]; per child an index and a count:
   count > 0: a leaf of `count` triangle blocks from block `index` of the object; count == 0,
   index != 0: an inner child (node `index` of the
   object); both 0: an unused slot (empty box). Node 0 of an object holds only its root box
   (slot 0, the inner child 1): the twin of the CPU's first test of WideBvhT::bounds. */
typedef struct __attribute__((aligned(64))) {
    float planes[6][RK_WIDTH];
    uint index[RK_WIDTH];
    uint count[RK_WIDTH];
} rk_wnode;

/* rk_wnode with its child boxes quantized to bytes (raykit::cl::QuantizedNode, 104 bytes against
   256): plane (row r = 2 * axis + hi, child c) is origin[axis] + q[r][c] * 2^exponent[axis] in
   float, rounded outward on the host (cl/device_tree.hpp quantize_node) so that it holds the
   child's box; bit c of `used` is set for a slot in use; index and count as rk_wnode's. */
typedef struct {
    float origin[3];
    char exponent[3];
    uchar used;
    uchar q[6][RK_WIDTH];
    uint index[RK_WIDTH];
    uchar count[RK_WIDTH];
} rk_qnode;

/* Four triangles' vertices in leaf order (raykit::TriangleBlock4): p[3 * corner + axis][lane];
   unused lanes repeat the leaf's last triangle. */
typedef struct __attribute__((aligned(32))) {
    float p[9][4];
    uint prim[4];
} rk_block;

/* Triangle (raykit::Triangle): three vertex indices, relative to the object's first vertex. */
typedef struct {
    uint v[3];
} rk_triangle;

/* Vertex as a vertex hook sees it (raykit::Vertex). */
typedef struct {
    float position[3];
    float normal[3];
    float uv[2];
} rk_vertex;

/* Ray (raykit::Ray): org + t * dir for t in [tmin, tmax]. */
typedef struct {
    float org[3];
    float tmin;
    float dir[3];
    float tmax;
} rk_ray;

/* Hit (raykit::Hit): prim == RK_INVALID on a miss. */
typedef struct {
    float t;
    float u;
    float v;
    uint prim;
    uint inst;
} rk_hit;

/* Pinhole camera, per-frame constants (raykit::CameraFrame). Direction through
   the image point (fx, fy) (pixel units, (0,0) = top-left corner):
   fma(fy, dv, fma(fx, du, corner)). */
typedef struct {
    float origin[3];
    float corner[3];
    float du[3];
    float dv[3];
    uint width;
    uint height;
} rk_camera;

/* Instance (raykit::cl::InstanceRecord): row-major 3x4 affine transforms;
   identity != 0: the transform is the identity, rays and surfaces are not mapped. */
typedef struct {
    float world_to_object[12];
    float object_to_world[12];
    uint object;
    uint identity;
    uint pad1;
    uint pad2;
} rk_instance;

/* Object (raykit::cl::ObjectRecord): where its parts start in the scene's
   concatenated node, block, triangle and vertex arrays. Node and block indices
   and triangle vertex indices stored there are relative to them. */
typedef struct {
    uint node_offset;
    uint node_count;
    uint block_offset;
    uint triangle_offset;
    uint vertex_offset;
    uint vertex_count;
    uint triangle_count;
    uint pad;
} rk_object;

#define RK_INVALID 0xFFFFFFFFu

/* Helpers for vertex hooks. */
float3 rk_vertex_position(rk_vertex v) { return (float3)(v.position[0], v.position[1], v.position[2]); }
float3 rk_vertex_normal(rk_vertex v) { return (float3)(v.normal[0], v.normal[1], v.normal[2]); }
rk_vertex rk_vertex_set_position(rk_vertex v, float3 p) {
    v.position[0] = p.x; v.position[1] = p.y; v.position[2] = p.z;
    return v;
}
rk_vertex rk_vertex_set_normal(rk_vertex v, float3 n) {
    v.normal[0] = n.x; v.normal[1] = n.y; v.normal[2] = n.z;
    return v;
}
)CLC";

}  // namespace raykit::kernels
