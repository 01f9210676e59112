// Refit against rebuild over an animation that first keeps and then breaks
// neighbourhoods. Prints one CSV row per frame:
//   frame,phase,sah_refit,sah_fresh,growth,steps_refit,steps_fresh,refit_ms,build_ms
// growth = sah_refit / sah_fresh; steps = inner nodes + leaves visited per ray
// on the same random rays (a deterministic measure of trace cost). Timing
// columns are medians of 5 runs in this process.
//
//   refit_vs_rebuild [--tris N] [--frames F] > refit.csv
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "raykit.hpp"
#include "raykit/scene/generate.hpp"

using namespace raykit;

namespace {

double median_ms(const std::vector<double>& v) {
    std::vector<double> s = v;
    std::sort(s.begin(), s.end());
    return s[s.size() / 2];
}

template <class F>
double time_ms(F&& f, int reps = 5) {
    std::vector<double> t;
    for (int i = 0; i < reps; ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        f();
        t.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    }
    return median_ms(t);
}

double steps_per_ray(const Mesh& m, const Bvh& bvh, const std::vector<Ray>& rays) {
    TraversalStats st;
    for (const Ray& r : rays) intersect_closest(m, bvh, r, &st);
    return double(st.nodes + st.leaves) / double(rays.size());
}

}  // namespace

int main(int argc, char** argv) {
    std::size_t tris = 200000;
    int frames = 60;
    for (int i = 1; i + 1 < argc; i += 2) {
        if (!std::strcmp(argv[i], "--tris")) tris = std::stoul(argv[i + 1]);
        if (!std::strcmp(argv[i], "--frames")) frames = std::stoi(argv[i + 1]);
    }
    const Mesh rest = make_bumpy_torus(tris);
    Mesh m = rest;
    const Bvh built = build_bvh(m);
    Bvh refitted = built;
    // "hand": the vertices within a 60-degree sector of the torus
    std::vector<std::uint8_t> hand(rest.positions.size());
    for (std::size_t i = 0; i < hand.size(); ++i) hand[i] = std::atan2(rest.positions[i].y, rest.positions[i].x) > 2.0f;
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> U(-1.5f, 1.5f), N(-1.0f, 1.0f);
    std::vector<Ray> rays(20000);
    for (Ray& r : rays) {
        r.org = vec3(U(rng), U(rng), U(rng) * 0.5f);
        r.dir = vec3(N(rng), N(rng), N(rng));
    }
    std::printf("frame,phase,sah_refit,sah_fresh,growth,steps_refit,steps_fresh,refit_ms,build_ms\n");
    const int half = frames / 2;
    for (int f = 0; f <= frames; ++f) {
        // phase 0 (wave): every vertex moves a little, neighbourhoods kept.
        // phase 1 (throw): the hand sector flies off rigidly, further each frame.
        const float t = float(f) / float(half);
        for (std::size_t i = 0; i < m.positions.size(); ++i) {
            const vec3 p = rest.positions[i];
            vec3 q = p + vec3(0.0f, 0.0f, 0.08f * std::sin(6.0f * p.x + 3.0f * t));
            if (f > half && hand[i]) q += vec3(-0.5f, 1.0f, 0.6f) * (float(f - half) / float(half)) * 2.5f;
            m.positions[i] = q;
        }
        const MeshView view(m);
        const double refit_ms = time_ms([&] {
            refitted = built;
            refit(refitted, [&](std::uint32_t i) { return view.bounds(i); });
        });
        Bvh fresh;
        const double build_ms = time_ms([&] { fresh = build_bvh(m); }, 3);
        const double sr = sah_cost(refitted), sf = sah_cost(fresh);
        std::printf("%d,%s,%.4f,%.4f,%.4f,%.2f,%.2f,%.3f,%.3f\n", f, f > half ? "throw" : "wave", sr, sf, sr / sf,
                    steps_per_ray(m, refitted, rays), steps_per_ray(m, fresh, rays), refit_ms, build_ms);
        std::fflush(stdout);
    }
}
