// example_ray_hook: a custom ray hook, rendered on the CPU and on the OpenCL device.
//
//   example_ray_hook [MESH.obj] [OUT_PREFIX]
//
// A ray hook decides what a traced ray contributes: FogHook (fog_hook.hpp, next to this file)
// shades each hit with a diffuse term and shadow rays, seen through exponential fog. One C++
// type carries both sides: `shade`, called by render_hook_cpu, and `source`, OpenCL C that the
// device renderer compiles into its program. The scene (a floor, the given mesh or an icosphere,
// and a torus) is rendered both ways; the two images must agree to 2/255 per channel, since the
// device follows the CPU ray for ray and only the last bits of the colours may differ.
// Writes OUT_PREFIX_cpu.png and OUT_PREFIX_device.png. Exits 77 when there is no OpenCL device.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include <glm/gtc/matrix_transform.hpp>
#include <raykit.hpp>
#include <raykit/cl.hpp>

#include "fog_hook.hpp"

int main(int argc, char** argv) {
    using namespace raykit;
    const std::string prefix =
        argc > 2 ? argv[2] : (std::filesystem::temp_directory_path() / "example_ray_hook").string();
    raykit::cl::Device* dev = nullptr;
    try {
        dev = &raykit::cl::Device::shared();  // RAYKIT_CL_DEVICE picks another (see `raykit info --device`)
    } catch (const raykit::cl::NoDeviceError& e) {
        std::printf("no OpenCL device, nothing to compare: %s\n", e.what());
        return 77;
    }

    // The scene: three objects placed by instances (see example_instances).
    Mesh floor;
    floor.positions = {{-4, 0, -4}, {4, 0, -4}, {4, 0, 4}, {-4, 0, 4}};
    floor.triangles = {{{0, 2, 1}}, {{0, 3, 2}}};  // counter-clockwise seen from above
    floor.material_ids.assign(2, kNoMaterial);     // the default material
    Mesh ball = argc > 1 ? load_obj(argv[1]) : make_icosphere(3);
    const AABB box = ball.bounds();  // fit into the unit sphere
    const float fit = 2.0f / std::max(glm::length(box.max - box.min), 1e-6f);
    transform_positions(ball, fit, -box.center() * fit);
    RenderScene rs;
    rs.scene.add_instance(rs.add_object(std::move(floor)));
    rs.scene.add_instance(rs.add_object(std::move(ball)), glm::translate(mat4(1.0f), vec3(-1.0f, 1.0f, 0.0f)));
    rs.scene.add_instance(rs.add_object(make_bumpy_torus(4000)),
                          glm::rotate(glm::translate(mat4(1.0f), vec3(1.5f, 0.6f, -1.5f)), 1.2f, vec3(1.0f, 0.0f, 0.0f)));
    rs.scene.update_top_level();
    const Camera cam{.position = {0.0f, 3.0f, 7.0f}, .target = {0.0f, 0.5f, 0.0f}, .width = 256, .height = 192};
    rs.lights.push_back(default_key_light(cam));

    // The hook's parameters and the renderer's settings are the same on both sides.
    RenderSettings set;
    set.spp = 4;
    set.shade.ambient = vec3(0.1f);
    const FogHook::Params fog{0.1f, 0.35f, 0.45f, 0.6f};  // density per unit distance, linear fog colour

    const Image cpu = render_hook_cpu<FogHook>(rs.view(), cam, set, fog);
    raykit::cl::DeviceRenderer renderer(*dev, rs.view());  // uploads the scene once
    const Image gpu = renderer.render_hook<FogHook>(cam, set, fog);
    write_png(cpu, prefix + "_cpu.png");
    write_png(gpu, prefix + "_device.png");

    // The oracle for the device is the CPU. A pixel whose samples all missed shows the fog colour
    // (alpha = the fraction of samples that hit): a check of the hook itself.
    std::size_t differ = 0, missed = 0, wrong_fog = 0;
    float worst = 0.0f;
    for (std::size_t i = 0; i < cpu.pixels.size(); ++i) {
        float d = 0.0f;
        for (int c = 0; c < 4; ++c) d = std::max(d, std::fabs(cpu.pixels[i][c] - gpu.pixels[i][c]));
        worst = std::max(worst, d);
        differ += !(d <= 2.0f / 255.0f);
        if (cpu.pixels[i].a != 0.0f) continue;
        ++missed;
        wrong_fog += glm::length(vec3(cpu.pixels[i]) - vec3(fog.r, fog.g, fog.b)) > 1e-5f;  // the mean of spp equal samples
    }
    std::printf("device: %s\nwrote %s_cpu.png and %s_device.png (%u x %u, %u samples per pixel)\n",
                dev->info().label().c_str(), prefix.c_str(), prefix.c_str(), cam.width, cam.height, set.spp);
    std::printf("CPU against device: %zu of %zu pixels differ by more than 2/255 (largest difference %.2g/255)\n",
                differ, cpu.pixels.size(), double(worst) * 255.0);
    std::printf("%zu pixels saw only fog: %zu of them not the fog colour\n", missed, wrong_fog);
    const bool ok = differ == 0 && wrong_fog == 0 && missed > 0 && missed < cpu.pixels.size();
    if (!ok) std::printf("FAILED\n");
    return ok ? 0 : 1;
}
