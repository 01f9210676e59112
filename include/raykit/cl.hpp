// raykit/cl.hpp — the OpenCL device path of raykit (needs OpenCL headers and
// a loader; link the raykit::cl CMake target). raykit.hpp never includes it.
//
//   cl/error.hpp         Error (names the call and CL_... code), NoDeviceError, BuildError
//   cl/device.hpp        list_devices, choose_device (RAYKIT_CL_DEVICE), Device::shared
//   cl/program.hpp       SourcePart, assemble (#line per part), build_program (cached)
//   cl/buffer.hpp        typed device buffers
//   cl/layout.hpp        host twins of the crossing structs, check_layout()
//   cl/trace.hpp         MeshTracer: closest/any hit of one mesh, camera rays
//   cl/hook.hpp          vertex hooks (OpenCL C + parameter struct + CPU twin)
//   cl/refit.hpp         device refit, level-wise and one-pass
//   cl/render.hpp        wavefront renderer with ray hooks (normals, depth, whitted)
//   cl/device_scene.hpp  DeviceScene<Hooks...>: two-level scene pipeline
//
// Kernel sources are raw strings in kernels/raykit/kernels/ (no files are
// read at run time).
#pragma once

#include "raykit.hpp"
#include "raykit/scene/camera.hpp"
#include "raykit/scene/scene.hpp"

#include "raykit/cl/error.hpp"
#include "raykit/cl/device.hpp"
#include "raykit/cl/program.hpp"
#include "raykit/cl/buffer.hpp"
#include "raykit/cl/layout.hpp"
#include "raykit/cl/device_tree.hpp"
#include "raykit/cl/trace.hpp"
#include "raykit/cl/hook.hpp"
#include "raykit/cl/refit.hpp"
#include "raykit/cl/device_build.hpp"
#include "raykit/cl/render.hpp"
#include "raykit/cl/device_scene.hpp"
