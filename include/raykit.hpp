// raykit.hpp — everything on the CPU side of raykit: every public header outside raykit/cl/
// (tests/umbrella_check.cmake keeps it so). For tracing alone, raykit/core.hpp is enough.
//
// Layers (each includes only the ones above it in this list):
//   util/, math/     vectors, AABB, ray, hit, float utilities, the executor, the block cache, radix sort
//   simd/            the instruction-set levels and the CPU's (isa.hpp; scene/trace.hpp compiles
//                    the walks once per level and calls the CPU's)
//   intersect/       slab test, triangle tests (Watertight default, MollerTrumbore, ThesisTest)
//   bvh/             node layout, builders, SAH cost, validate, traverse, refit
//   scene/           mesh, skeleton and skin data, building a BVH over a mesh, closest/any-hit queries
//   io/              OBJ/MTL and SMD loading, ParseError
//   anim/            skeletons, keyframe interpolation, skinning, the skinning vertex hook
//   render/          materials, textures, images, shaders, ray hooks, the CPU renderer, the frame loop
// The OpenCL device path is separate: include raykit/cl.hpp.
#pragma once

#include "raykit/config.hpp"
#include "raykit/core.hpp"
#include "raykit/util/parallel.hpp"
#include "raykit/util/block_cache.hpp"
#include "raykit/util/raw_array.hpp"
#include "raykit/util/radix_sort.hpp"
#include "raykit/math/types.hpp"
#include "raykit/math/aabb.hpp"
#include "raykit/math/ray.hpp"
#include "raykit/math/hit.hpp"
#include "raykit/math/offset.hpp"
#include "raykit/math/limits.hpp"
#include "raykit/simd/isa.hpp"
#include "raykit/intersect/slab.hpp"
#include "raykit/intersect/triangle.hpp"
#include "raykit/intersect/triangle4.hpp"
#include "raykit/bvh/node.hpp"
#include "raykit/bvh/depth.hpp"
#include "raykit/bvh/sah.hpp"
#include "raykit/bvh/validate.hpp"
#include "raykit/bvh/sanitize.hpp"
#include "raykit/bvh/morton.hpp"
#include "raykit/bvh/binned_sah.hpp"
#include "raykit/bvh/bottom_up.hpp"
#include "raykit/bvh/pairwise.hpp"
#include "raykit/bvh/sortaxis.hpp"
#include "raykit/bvh/ploc.hpp"
#include "raykit/bvh/optimize.hpp"
#include "raykit/bvh/refit.hpp"
#include "raykit/bvh/rebuild_policy.hpp"
#include "raykit/bvh/traverse.hpp"
#include "raykit/bvh/wide.hpp"
#include "raykit/bvh/traverse_packet.hpp"
#include "raykit/bvh/traverse_wide.hpp"
#include "raykit/scene/mesh.hpp"
#include "raykit/scene/skeleton_data.hpp"
#include "raykit/scene/build_options.hpp"
#include "raykit/scene/build.hpp"
#include "raykit/scene/generate.hpp"
#include "raykit/scene/trace.hpp"
#include "raykit/scene/block_bvh.hpp"
#include "raykit/scene/camera.hpp"
#include "raykit/scene/scene.hpp"
#include "raykit/io/parse_error.hpp"
#include "raykit/io/lexer.hpp"
#include "raykit/io/obj.hpp"
#include "raykit/io/obj_write.hpp"
#include "raykit/io/smd.hpp"
#include "raykit/io/rays.hpp"
#include "raykit/anim/skeleton.hpp"
#include "raykit/anim/interpolate.hpp"
#include "raykit/anim/skinning.hpp"
#include "raykit/anim/skin_hook.hpp"
#include "raykit/render/image.hpp"
#include "raykit/render/image_decode.hpp"
#include "raykit/render/texture.hpp"
#include "raykit/render/material.hpp"
#include "raykit/render/shade.hpp"
#include "raykit/render/ray_hook.hpp"
#include "raykit/render/shaders.hpp"
#include "raykit/render/render_cpu.hpp"
#include "raykit/render/frame.hpp"
