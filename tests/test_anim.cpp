// Tests for raykit/anim/: skeleton, interpolation, packed linear blend
// skinning, the `raykit skin` command (examples/cli_skin.hpp) and the
// arguments of `raykit animate` (examples/cli_animate.hpp; its rendering is
// tested through the executable in test_cli.cpp).
//
// The oracle is written independently of the library: its own SMD reader
// (std::istringstream), rotation matrices built from explicit sin/cos
// (Rz * Ry * Rx), world transforms by recursion, slerp as R0 * exp(t log(R0^T R1))
// with Rodrigues' formula (no quaternions), the Euler option as per-axis
// wrapping arithmetic, and skinning as a sum of per-bone transformed points
// in double precision.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "../examples/cli_animate.hpp"
#include "../examples/cli_skin.hpp"
#include "raykit/anim/interpolate.hpp"
#include "raykit/anim/skeleton.hpp"
#include "raykit/anim/skinning.hpp"
#include "raykit/io/smd.hpp"

namespace fs = std::filesystem;
using raykit::BonePose;
using raykit::Interpolation;
using raykit::SmdModel;
using raykit::SmdSkeletonAnim;
using raykit::vec3;
using raykit::WrapMode;

namespace {

constexpr double kPi = std::numbers::pi;

fs::path fixture_dir() { return fs::path(RAYKIT_TEST_DATA_DIR) / "smd"; }

fs::path shared_smd_dir() {
#ifdef RAYKIT_SHARED_DATA_DIR
    return fs::path(RAYKIT_SHARED_DATA_DIR) / "smd";
#else
    return fs::path(__FILE__).parent_path().parent_path().parent_path() / "shared" / "data" / "smd";
#endif
}

// ------------------------------------------------------------------ oracle: matrices

using V3 = std::array<double, 3>;
using M3 = std::array<V3, 3>;  // rows

M3 identity3() { return {V3{1, 0, 0}, V3{0, 1, 0}, V3{0, 0, 1}}; }
M3 rot_x(double a) {
    const double c = std::cos(a), s = std::sin(a);
    return {V3{1, 0, 0}, V3{0, c, -s}, V3{0, s, c}};
}
M3 rot_y(double a) {
    const double c = std::cos(a), s = std::sin(a);
    return {V3{c, 0, s}, V3{0, 1, 0}, V3{-s, 0, c}};
}
M3 rot_z(double a) {
    const double c = std::cos(a), s = std::sin(a);
    return {V3{c, -s, 0}, V3{s, c, 0}, V3{0, 0, 1}};
}
M3 mul(const M3& a, const M3& b) {
    M3 r{};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            for (int k = 0; k < 3; ++k) r[i][j] += a[i][k] * b[k][j];
    return r;
}
V3 mulv(const M3& a, const V3& v) {
    return {a[0][0] * v[0] + a[0][1] * v[1] + a[0][2] * v[2], a[1][0] * v[0] + a[1][1] * v[1] + a[1][2] * v[2],
            a[2][0] * v[0] + a[2][1] * v[1] + a[2][2] * v[2]};
}
M3 transpose(const M3& a) {
    M3 r{};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) r[i][j] = a[j][i];
    return r;
}
V3 add(const V3& a, const V3& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
V3 scale(const V3& a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
double dist(const V3& a, const V3& b) {
    return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}
double max_abs_diff(const M3& a, const M3& b) {
    double m = 0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) m = std::max(m, std::abs(a[i][j] - b[i][j]));
    return m;
}
/// Valve's SMD convention, built by hand.
M3 euler(double x, double y, double z) { return mul(rot_z(z), mul(rot_y(y), rot_x(x))); }

/// Rotation by `angle` about the unit `axis` (Rodrigues).
M3 axis_angle(const V3& k, double angle) {
    const double c = std::cos(angle), s = std::sin(angle), C = 1 - c;
    return {V3{c + k[0] * k[0] * C, k[0] * k[1] * C - k[2] * s, k[0] * k[2] * C + k[1] * s},
            V3{k[1] * k[0] * C + k[2] * s, c + k[1] * k[1] * C, k[1] * k[2] * C - k[0] * s},
            V3{k[2] * k[0] * C - k[1] * s, k[2] * k[1] * C + k[0] * s, c + k[2] * k[2] * C}};
}

/// Angle in [0, pi] and unit axis of a rotation matrix.
void rotation_log(const M3& r, double& angle, V3& axis) {
    const double tr = r[0][0] + r[1][1] + r[2][2];
    angle = std::acos(std::clamp((tr - 1) / 2, -1.0, 1.0));
    if (angle < 1e-12) {
        axis = {1, 0, 0};
        return;
    }
    if (angle < kPi - 1e-4) {
        V3 a{r[2][1] - r[1][2], r[0][2] - r[2][0], r[1][0] - r[0][1]};
        axis = scale(a, 1 / (2 * std::sin(angle)));
        return;
    }
    // Near pi: the axis from the symmetric part, the sign from the largest component.
    int i = 0;
    if (r[1][1] > r[i][i]) i = 1;
    if (r[2][2] > r[i][i]) i = 2;
    V3 a{};
    a[i] = std::sqrt(std::max(0.0, (r[i][i] + 1) / 2));
    for (int j = 0; j < 3; ++j) {
        if (j != i) a[j] = (r[i][j] + r[j][i]) / (4 * a[i]);
    }
    const double n = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    axis = scale(a, 1 / n);
}

/// The geodesic interpolation between two rotations (what slerp computes).
M3 geodesic(const M3& r0, const M3& r1, double t) {
    double angle = 0;
    V3 axis{};
    rotation_log(mul(transpose(r0), r1), angle, axis);
    return mul(r0, axis_angle(axis, t * angle));
}

double wrap_pi(double d) {
    while (d > kPi) d -= 2 * kPi;
    while (d < -kPi) d += 2 * kPi;
    return d;
}

struct Rigid {
    M3 r = identity3();
    V3 t{0, 0, 0};
};
Rigid compose(const Rigid& a, const Rigid& b) { return {mul(a.r, b.r), add(mulv(a.r, b.t), a.t)}; }
Rigid inverse(const Rigid& a) {
    const M3 rt = transpose(a.r);
    return {rt, scale(mulv(rt, a.t), -1)};
}
V3 xform(const Rigid& a, const V3& p) { return add(mulv(a.r, p), a.t); }

// ------------------------------------------------------------------ oracle: SMD reader

using Pose6 = std::array<double, 6>;  // px py pz rx ry rz

struct OracleCorner {
    V3 pos{};
    V3 nrm{};
    std::map<int, double> weights;
};

struct OracleFile {
    std::vector<std::string> name;
    std::vector<int> parent;
    std::vector<std::vector<Pose6>> frames;        // [frame][bone], frame = time - first time
    std::vector<std::vector<bool>> present;        // [frame][bone]: set in that frame or before
    std::vector<OracleCorner> corners;
};

OracleFile oracle_read(const fs::path& file) {
    std::ifstream in(file, std::ios::binary);
    OracleFile o;
    std::string line;
    std::string block;
    int corner = -1;
    long first_time = 0;
    while (std::getline(in, line)) {
        if (!line.empty() && line.back() == '\r') line.pop_back();
        std::istringstream s(line);
        std::string first;
        if (!(s >> first) || first.rfind("//", 0) == 0) continue;
        if (block.empty()) {
            if (first == "nodes" || first == "skeleton" || first == "triangles") block = first;
            continue;
        }
        if (first == "end" && corner < 0) {
            block.clear();
            continue;
        }
        if (block == "nodes") {
            const int id = std::stoi(first);
            const std::size_t q0 = line.find('"'), q1 = line.find('"', q0 + 1);
            const int parent = std::stoi(line.substr(q1 + 1));
            if (static_cast<std::size_t>(id) >= o.name.size()) {
                o.name.resize(static_cast<std::size_t>(id) + 1);
                o.parent.resize(static_cast<std::size_t>(id) + 1);
            }
            o.name[static_cast<std::size_t>(id)] = line.substr(q0 + 1, q1 - q0 - 1);
            o.parent[static_cast<std::size_t>(id)] = parent;
        } else if (block == "skeleton") {
            if (first == "time") {
                // Every frame number gets its own copy: a gap repeats the frame before it.
                long t = 0;
                s >> t;
                if (o.frames.empty()) {
                    first_time = t;
                    o.frames.emplace_back(o.name.size());
                    o.present.emplace_back(o.name.size(), false);
                }
                while (static_cast<long>(o.frames.size()) <= t - first_time) {
                    o.frames.push_back(o.frames.back());
                    o.present.push_back(o.present.back());
                }
                continue;
            }
            const int b = std::stoi(first);
            Pose6 p{};
            for (double& v : p) s >> v;
            o.frames.back()[static_cast<std::size_t>(b)] = p;
            o.present.back()[static_cast<std::size_t>(b)] = true;
        } else if (block == "triangles") {
            if (corner < 0) {
                corner = 0;
                continue;
            }
            OracleCorner c;
            const int parent = std::stoi(first);
            double uv[2];
            s >> c.pos[0] >> c.pos[1] >> c.pos[2] >> c.nrm[0] >> c.nrm[1] >> c.nrm[2] >> uv[0] >> uv[1];
            int links = 0;
            double sum = 0;
            if (s >> links) {
                for (int k = 0; k < links; ++k) {
                    int b = 0;
                    double w = 0;
                    s >> b >> w;
                    c.weights[b] += w;
                    sum += w;
                }
            }
            if (links == 0) {
                c.weights = {{parent, 1.0}};
            } else {
                if (sum < 1 - 1e-5) {
                    c.weights[parent] += 1 - sum;
                    sum = 1;
                }
                for (auto& [b, w] : c.weights) w /= sum;
            }
            o.corners.push_back(c);
            if (++corner == 3) corner = -1;
        }
    }
    return o;
}

double extent_of(const OracleFile& o) {
    V3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    for (const OracleCorner& c : o.corners) {
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], c.pos[k]);
            hi[k] = std::max(hi[k], c.pos[k]);
        }
    }
    return dist(lo, hi);
}

/// Skinned corner positions (and normals) of `ref` posed by `anim` at the
/// fractional frame `frame` (clamped), or the bind pose when anim is null.
struct OracleSkin {
    std::vector<V3> pos, nrm;
};

OracleSkin oracle_skin(const OracleFile& ref, const OracleFile* anim, double frame, bool slerp) {
    const std::size_t n = ref.name.size();
    // Local transform of each reference bone.
    std::vector<Rigid> local(n);
    for (std::size_t b = 0; b < n; ++b) {
        Pose6 p0 = ref.frames[0][b], p1 = p0;
        double t = 0;
        if (anim) {
            const double last = static_cast<double>(anim->frames.size() - 1);
            const double f = std::min(std::max(frame, 0.0), last);
            const auto f0 = static_cast<std::size_t>(std::floor(f));
            const std::size_t f1 = std::min(f0 + 1, anim->frames.size() - 1);
            t = f - static_cast<double>(f0);
            const auto it = std::find(anim->name.begin(), anim->name.end(), ref.name[b]);
            if (it != anim->name.end()) {
                const auto ab = static_cast<std::size_t>(it - anim->name.begin());
                if (anim->present[f0][ab]) p0 = anim->frames[f0][ab];
                if (anim->present[f1][ab]) p1 = anim->frames[f1][ab];
            }
        }
        Rigid& L = local[b];
        for (int k = 0; k < 3; ++k) L.t[k] = p0[k] + t * (p1[k] - p0[k]);
        if (slerp) {
            L.r = geodesic(euler(p0[3], p0[4], p0[5]), euler(p1[3], p1[4], p1[5]), t);
        } else {
            L.r = euler(p0[3] + t * wrap_pi(p1[3] - p0[3]), p0[4] + t * wrap_pi(p1[4] - p0[4]),
                        p0[5] + t * wrap_pi(p1[5] - p0[5]));
        }
    }
    std::vector<Rigid> bind_local(n);
    for (std::size_t b = 0; b < n; ++b) {
        const Pose6& p = ref.frames[0][b];
        bind_local[b] = {euler(p[3], p[4], p[5]), V3{p[0], p[1], p[2]}};
    }
    // World transforms by recursion.
    auto world_of = [&](const std::vector<Rigid>& loc) {
        std::vector<Rigid> w(n);
        std::vector<bool> done(n, false);
        auto rec = [&](auto&& self, std::size_t b) -> const Rigid& {
            if (!done[b]) {
                const int p = ref.parent[b];
                w[b] = p < 0 ? loc[b] : compose(self(self, static_cast<std::size_t>(p)), loc[b]);
                done[b] = true;
            }
            return w[b];
        };
        for (std::size_t b = 0; b < n; ++b) rec(rec, b);
        return w;
    };
    const std::vector<Rigid> world = world_of(local), bind = world_of(bind_local);
    std::vector<Rigid> skin(n);
    for (std::size_t b = 0; b < n; ++b) skin[b] = compose(world[b], inverse(bind[b]));
    OracleSkin out;
    for (const OracleCorner& c : ref.corners) {
        V3 p{0, 0, 0}, q{0, 0, 0};
        for (const auto& [b, w] : c.weights) {
            p = add(p, scale(xform(skin[static_cast<std::size_t>(b)], c.pos), w));
            q = add(q, scale(mulv(skin[static_cast<std::size_t>(b)].r, c.nrm), w));
        }
        const double len = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        out.pos.push_back(p);
        out.nrm.push_back(len > 0 ? scale(q, 1 / len) : q);
    }
    return out;
}

// ------------------------------------------------------------------ the library's side

struct Posed {
    std::vector<vec3> pos, nrm;  // per corner
};

Posed library_skin(const SmdModel& m, const SmdSkeletonAnim* anim, double frame, Interpolation mode,
                   unsigned threads = 0) {
    const raykit::Skeleton sk(m);
    const std::vector<raykit::BoneTransform> local =
        anim ? raykit::sample_frame(*anim, frame, mode) : sk.bind_transforms();
    const auto mats = raykit::skin_matrices(sk, local);
    const auto packed = raykit::pack_skin(m.weights, m.bones.size());
    std::vector<vec3> p(m.mesh.positions.size()), n(m.mesh.positions.size());
    raykit::skin_vertices(packed, mats, m.mesh.positions, m.mesh.normals, p, n, threads);
    Posed out;
    for (const raykit::Triangle& t : m.mesh.triangles) {
        for (int c = 0; c < 3; ++c) {
            out.pos.push_back(p[t.v[c]]);
            out.nrm.push_back(n[t.v[c]]);
        }
    }
    return out;
}

V3 to_v3(const vec3& v) { return {v.x, v.y, v.z}; }

/// Largest corner distance between the library and the oracle.
double compare(const Posed& lib, const OracleSkin& ora, double* worst_normal = nullptr) {
    EXPECT_EQ(lib.pos.size(), ora.pos.size());
    double worst = 0, worst_n = 0;
    for (std::size_t i = 0; i < std::min(lib.pos.size(), ora.pos.size()); ++i) {
        worst = std::max(worst, dist(to_v3(lib.pos[i]), ora.pos[i]));
        worst_n = std::max(worst_n, dist(to_v3(lib.nrm[i]), ora.nrm[i]));
    }
    if (worst_normal) *worst_normal = worst_n;
    return worst;
}

M3 to_m3(const glm::dquat& q) {
    const glm::dmat3 m = glm::mat3_cast(q);
    M3 r{};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) r[i][j] = m[j][i];
    return r;
}

// ------------------------------------------------------------------ skeleton

TEST(AnimSkeleton, EulerConventionIsRzRyRx) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> U(-4.0, 4.0);
    for (int i = 0; i < 200; ++i) {
        const double x = U(rng), y = U(rng), z = U(rng);
        const glm::dmat3 m = raykit::euler_xyz_matrix(glm::dvec3(x, y, z));
        M3 r{};
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) r[a][b] = m[b][a];
        ASSERT_LT(max_abs_diff(r, euler(x, y, z)), 1e-12) << x << " " << y << " " << z;
    }
    // One hand-checked case: Rz(90) after Rx(90) takes +y to +z, then +z stays +z.
    const glm::dvec3 v = raykit::euler_xyz_matrix(glm::dvec3(kPi / 2, 0, kPi / 2)) * glm::dvec3(0, 1, 0);
    EXPECT_NEAR(v.x, 0, 1e-15);
    EXPECT_NEAR(v.y, 0, 1e-15);
    EXPECT_NEAR(v.z, 1, 1e-15);
}

TEST(AnimSkeleton, WorldMatricesAndOrderOnTheFixture) {
    const SmdModel m = raykit::load_smd_reference(fixture_dir() / "ref_weights.SMD");
    const raykit::Skeleton sk(m);
    ASSERT_EQ(sk.size(), 4u);
    // Parents before children although the file lists arm before torso before hips.
    std::vector<std::size_t> pos(4);
    for (std::size_t i = 0; i < 4; ++i) pos[sk.order()[i]] = i;
    for (std::size_t b = 0; b < 4; ++b) {
        if (m.bones[b].parent >= 0) {
            EXPECT_LT(pos[static_cast<std::size_t>(m.bones[b].parent)], pos[b]);
        }
    }
    // Hand-computed: hips at (0,0,1); torso at hips + (0,0,2) rotated 90 deg about z;
    // arm at torso + Rz(90)(1,0,0) = (0,1,3); prop (second root) at (5,0,0).
    const auto& w = sk.bind_world();
    const double e = 1e-6;
    EXPECT_NEAR(w[1][3].z, 3.0, e);
    EXPECT_NEAR(w[2][3].x, 0.0, e);
    EXPECT_NEAR(w[2][3].y, 1.0, e);
    EXPECT_NEAR(w[2][3].z, 3.0, e);
    EXPECT_NEAR(w[3][3].x, 5.0, e);
    EXPECT_NEAR(w[2][0].y, 1.0, e);  // the arm's x axis points along +y
    // world * inverse_bind of the bind pose is the identity.
    const auto s = sk.skinning_matrices(sk.bind_transforms());
    for (const auto& mm : s) {
        for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 4; ++r) EXPECT_NEAR(mm[c][r], c == r ? 1.0 : 0.0, 1e-15);
    }
}

TEST(AnimSkeleton, ValveConventionPutsGoblinVerticesNearTheirBones) {
    // A reference SMD stores its vertices in model space, so the bind pose
    // reproduces them under any Euler convention; the convention shows in
    // where the bones land. The goblin's root has large rotations about all
    // three axes: with Rz*Ry*Rx its vertices lie about 2.6 units from their
    // bone's origin on average, with the reverse order Rx*Ry*Rz about 7.6.
    const fs::path file = shared_smd_dir() / "hl2_goblin" / "Goblin_Reference.smd";
    if (!fs::exists(file)) GTEST_SKIP() << "shared SMD data not found";
    const SmdModel m = raykit::load_smd_reference(file);
    const raykit::Skeleton sk(m);
    const OracleFile o = oracle_read(file);
    std::vector<Rigid> alt(o.name.size());
    std::vector<bool> done(o.name.size(), false);
    auto world_alt = [&](auto&& self, std::size_t b) -> const Rigid& {
        if (!done[b]) {
            const Pose6& p = o.frames[0][b];
            const Rigid local{mul(rot_x(p[3]), mul(rot_y(p[4]), rot_z(p[5]))), V3{p[0], p[1], p[2]}};
            const int parent = o.parent[b];
            alt[b] = parent < 0 ? local : compose(self(self, static_cast<std::size_t>(parent)), local);
            done[b] = true;
        }
        return alt[b];
    };
    double lib = 0, other = 0;
    for (std::size_t v = 0; v < m.mesh.positions.size(); ++v) {
        const std::uint32_t b = m.weights[v].links.at(0).bone;
        const V3 p = to_v3(m.mesh.positions[v]);
        const glm::dvec4 origin = sk.bind_world()[b][3];
        lib += dist(p, V3{origin.x, origin.y, origin.z});
        other += dist(p, world_alt(world_alt, b).t);
    }
    lib /= static_cast<double>(m.mesh.positions.size());
    other /= static_cast<double>(m.mesh.positions.size());
    std::printf("[ info     ] goblin: mean vertex-to-bone distance %.3f (Rz*Ry*Rx) vs %.3f (Rx*Ry*Rz)\n", lib, other);
    EXPECT_LT(lib, 0.5 * other);
}

TEST(AnimSkeleton, RejectsBadHierarchies) {
    std::vector<BonePose> two(2);
    EXPECT_THROW(raykit::Skeleton({{"a", -1}, {"b", 0}}, std::vector<BonePose>(1)), std::invalid_argument);
    EXPECT_THROW(raykit::Skeleton({{"a", 1}, {"b", 0}}, two), std::invalid_argument);
    EXPECT_THROW(raykit::Skeleton({{"a", -1}, {"b", 2}}, two), std::invalid_argument);
    EXPECT_THROW(raykit::Skeleton({{"a", -1}, {"b", 1}}, two), std::invalid_argument);
    EXPECT_NO_THROW(raykit::Skeleton({{"a", 1}, {"b", -1}}, two));
    const raykit::Skeleton sk({{"a", -1}}, std::vector<BonePose>(1));
    std::vector<raykit::BoneTransform> wrong(3);
    EXPECT_THROW(sk.world_matrices(wrong), std::invalid_argument);
}

// ------------------------------------------------------------------ interpolation

TEST(AnimInterpolate, FrameBlendClampAndLoop) {
    auto fb = raykit::frame_blend(4, 2.25, WrapMode::clamp);
    EXPECT_EQ(fb.from, 2u);
    EXPECT_EQ(fb.to, 3u);
    EXPECT_DOUBLE_EQ(fb.t, 0.25);
    fb = raykit::frame_blend(4, -1.0, WrapMode::clamp);
    EXPECT_EQ(fb.from, 0u);
    EXPECT_EQ(fb.t, 0.0);
    fb = raykit::frame_blend(4, 3.0, WrapMode::clamp);
    EXPECT_EQ(fb.from, 3u);
    EXPECT_EQ(fb.to, 3u);
    EXPECT_EQ(fb.t, 0.0);
    fb = raykit::frame_blend(4, 99.0, WrapMode::clamp);
    EXPECT_EQ(fb.from, 3u);
    EXPECT_EQ(fb.t, 0.0);
    fb = raykit::frame_blend(4, 3.5, WrapMode::loop);
    EXPECT_EQ(fb.from, 3u);
    EXPECT_EQ(fb.to, 0u);
    EXPECT_DOUBLE_EQ(fb.t, 0.5);
    fb = raykit::frame_blend(4, 9.25, WrapMode::loop);
    EXPECT_EQ(fb.from, 1u);
    EXPECT_EQ(fb.to, 2u);
    EXPECT_DOUBLE_EQ(fb.t, 0.25);
    fb = raykit::frame_blend(4, -0.5, WrapMode::loop);
    EXPECT_EQ(fb.from, 3u);
    EXPECT_EQ(fb.to, 0u);
    EXPECT_DOUBLE_EQ(fb.t, 0.5);
    fb = raykit::frame_blend(1, 0.7, WrapMode::loop);
    EXPECT_EQ(fb.from, 0u);
    EXPECT_EQ(fb.to, 0u);
    EXPECT_THROW(raykit::frame_blend(0, 0.0, WrapMode::clamp), std::invalid_argument);
    EXPECT_THROW(raykit::frame_blend(3, std::nan(""), WrapMode::clamp), std::invalid_argument);
}

TEST(AnimInterpolate, ShortestAngleLerp) {
    EXPECT_NEAR(raykit::shortest_angle_lerp(3.0, -3.0, 0.5), kPi, 1e-12);  // across +pi, not through 0
    EXPECT_NEAR(raykit::shortest_angle_lerp(-3.0, 3.0, 0.5), -kPi, 1e-12);
    EXPECT_NEAR(raykit::shortest_angle_lerp(0.1, 0.3, 0.5), 0.2, 1e-12);
    EXPECT_NEAR(raykit::shortest_angle_lerp(0.0, 6.0, 1.0), 6.0 - 2 * kPi, 1e-12);
    EXPECT_EQ(raykit::shortest_angle_lerp(1.25, -2.0, 0.0), 1.25);
}

TEST(AnimInterpolate, SlerpBasics) {
    const glm::dquat a = raykit::euler_xyz_quat({0.3, -0.2, 1.0});
    const glm::dquat b = raykit::euler_xyz_quat({-0.5, 0.4, 2.0});
    const glm::dquat r0 = raykit::slerp_shortest(a, b, 0.0);
    EXPECT_EQ(r0.w, a.w);
    EXPECT_EQ(r0.x, a.x);
    EXPECT_LT(max_abs_diff(to_m3(raykit::slerp_shortest(a, b, 1.0)), to_m3(b)), 1e-12);
    // The sign of b does not matter (shorter arc).
    EXPECT_LT(max_abs_diff(to_m3(raykit::slerp_shortest(a, -b, 0.3)), to_m3(raykit::slerp_shortest(a, b, 0.3))),
              1e-12);
    // Half way about z.
    const glm::dquat h = raykit::slerp_shortest(raykit::euler_xyz_quat({0, 0, 0}), raykit::euler_xyz_quat({0, 0, 2.0}),
                                                0.5);
    EXPECT_LT(max_abs_diff(to_m3(h), rot_z(1.0)), 1e-12);
}

TEST(AnimInterpolate, RotationCrossingPi) {
    const SmdModel m = raykit::load_smd_reference(fixture_dir() / "ref_weights.SMD");
    const SmdSkeletonAnim a = raykit::load_smd_animation(fixture_dir() / "anim_weights.smd", m);
    // The arm (reference bone 2) turns from z = 3.0 to z = -3.0: the short way
    // is 2 pi - 6 = 0.283 rad through +pi, so half way is exactly Rz(pi) for
    // both schemes (a naive lerp would give Rz(0)).
    for (Interpolation mode : {Interpolation::slerp, Interpolation::euler}) {
        const auto local = raykit::sample_frame(a, 0.5, mode);
        const M3 r = to_m3(local[2].rotation);
        EXPECT_LT(max_abs_diff(r, rot_z(kPi)), 1e-7);
        EXPECT_GT(max_abs_diff(r, identity3()), 1.9);
        const auto quarter = raykit::sample_frame(a, 0.25, mode);
        EXPECT_LT(max_abs_diff(to_m3(quarter[2].rotation), rot_z(3.0 + 0.25 * (2 * kPi - 6.0))), 1e-7);
    }
}

TEST(AnimInterpolate, SeveralAxesSlerpAndEulerDifferByTheComputedAngle) {
    const SmdModel m = raykit::load_smd_reference(fixture_dir() / "ref_weights.SMD");
    const SmdSkeletonAnim a = raykit::load_smd_animation(fixture_dir() / "anim_weights.smd", m);
    // Arm: from (0,0,0) at frame 2 to (pi/2, pi/2, 0) at frame 3, i.e. R1 = Ry(90) Rx(90),
    // a rotation of 120 degrees about (1,1,-1)/sqrt(3).
    const auto s = raykit::sample_frame(a, 2.5, Interpolation::slerp);
    const auto e = raykit::sample_frame(a, 2.5, Interpolation::euler);
    const double h = static_cast<double>(1.570796f) / 2;  // half of the file's angle (pi/2 to 6 decimals)
    // slerp: half the angle about the same axis: 60 degrees.
    const V3 axis{1 / std::sqrt(3.0), 1 / std::sqrt(3.0), -1 / std::sqrt(3.0)};
    EXPECT_LT(max_abs_diff(to_m3(s[2].rotation), axis_angle(axis, kPi / 3)), 1e-6);
    // euler: each angle half way: Ry(45) Rx(45).
    EXPECT_LT(max_abs_diff(to_m3(e[2].rotation), mul(rot_y(h), rot_x(h))), 1e-12);
    // The two differ by the rotation angle theta with
    //   cos(theta/2) = q_slerp . q_euler
    //                = cos(30) cos^2(22.5) + (2 sin 22.5 cos 22.5 + sin^2 22.5) sin(30) / sqrt(3)
    const double c8 = std::cos(kPi / 8), s8 = std::sin(kPi / 8);
    const double expected = 2 * std::acos(std::cos(kPi / 6) * c8 * c8 + (2 * s8 * c8 + s8 * s8) * 0.5 / std::sqrt(3.0));
    EXPECT_NEAR(expected, 0.339837, 1e-6);  // about 19.47 degrees
    const double dot = std::abs(glm::dot(s[2].rotation, e[2].rotation));
    EXPECT_NEAR(2 * std::acos(std::min(dot, 1.0)), expected, 1e-5);
    // At the key frames the schemes agree.
    for (double f : {2.0, 3.0}) {
        const auto s2 = raykit::sample_frame(a, f, Interpolation::slerp);
        const auto e2 = raykit::sample_frame(a, f, Interpolation::euler);
        EXPECT_LT(max_abs_diff(to_m3(s2[2].rotation), to_m3(e2[2].rotation)), 1e-12);
    }
    // A vertex wholly on the arm: the skinned positions differ by |(Rs - Re) d|,
    // d = the vertex relative to the arm's bind origin, in the arm's bind frame.
    // Corner 8 is (0.5, 0.5, 3) on bone 2 whose bind origin is (0, 1, 3) with
    // its x axis along +y and y axis along -x: d = (-0.5, -0.5, 0).
    const V3 d{-0.5, -0.5, 0};
    const V3 ds = mulv(axis_angle(axis, kPi / 3), d), de = mulv(mul(rot_y(h), rot_x(h)), d);
    const Posed ps = library_skin(m, &a, 2.5, Interpolation::slerp);
    const Posed pe = library_skin(m, &a, 2.5, Interpolation::euler);
    EXPECT_NEAR(dist(to_v3(ps.pos[8]), to_v3(pe.pos[8])), dist(ds, de), 1e-5);
    EXPECT_GT(dist(ds, de), 0.1);
}

TEST(AnimInterpolate, TranslationsLerpAndTimeInSeconds) {
    const SmdModel m = raykit::load_smd_reference(fixture_dir() / "ref_weights.SMD");
    SmdSkeletonAnim a = raykit::load_smd_animation(fixture_dir() / "anim_weights.smd", m);
    // hips y: 0 at frame 1, 0.5 at frame 2.
    EXPECT_NEAR(raykit::sample_frame(a, 1.5)[0].translation.y, 0.25, 1e-12);
    EXPECT_NEAR(raykit::sample_time(a, 1.5 / 30.0)[0].translation.y, 0.25, 1e-12);
    a.fps = 10.0f;
    EXPECT_NEAR(raykit::sample_time(a, 0.175)[0].translation.y, 0.375, 1e-6);
    // Looping: 4 frames at 10 fps repeat every 0.4 s; 0.35 s is half way from frame 3 back to frame 0.
    EXPECT_NEAR(raykit::sample_time(a, 0.35, Interpolation::slerp, WrapMode::loop)[0].translation.y, 0.25, 1e-6);
    EXPECT_NEAR(raykit::sample_time(a, 0.35 + 0.4 * 7, Interpolation::slerp, WrapMode::loop)[0].translation.y, 0.25,
                1e-5);
    EXPECT_NEAR(raykit::sample_time(a, 0.35, Interpolation::slerp, WrapMode::clamp)[0].translation.y, 0.5, 1e-12);
}

// ------------------------------------------------------------------ packed layout

TEST(AnimPacked, LayoutSizes) {
    static_assert(sizeof(raykit::SkinMatrix) == 48);
    static_assert(sizeof(raykit::PackedLink) == 4);
    std::vector<raykit::VertexWeights> w(3);
    w[0].links = {{0, 1.0f}};
    w[1].links = {{1, 0.6f}, {2, 0.4f}};
    w[2].links = {{0, 0.4f}, {1, 0.3f}, {2, 0.3f}};
    const raykit::PackedSkin s = raykit::pack_skin(w, 3);
    EXPECT_EQ(s.vertex_count(), 3u);
    EXPECT_EQ(s.offsets, (std::vector<std::uint32_t>{0, 1, 3, 6}));
    EXPECT_EQ(s.bytes(), 4u * 4 + 6u * 4);  // 4 bytes per vertex (+1) and 4 per link
    EXPECT_EQ(s.links[0].weight, 65535);
    EXPECT_EQ(s.links[1].weight + s.links[2].weight, 65535);
    EXPECT_EQ(s.links[1].weight, 39321);  // round(0.6 * 65535)
    EXPECT_EQ(s.links[3].weight + s.links[4].weight + s.links[5].weight, 65535);
    EXPECT_EQ(s.links[3].bone, 0);
    EXPECT_EQ(s.links[5].bone, 2);
}

TEST(AnimPacked, RejectsBadWeightsAndDropsZeros) {
    std::vector<raykit::VertexWeights> w(1);
    w[0].links = {{5, 1.0f}};
    EXPECT_THROW(raykit::pack_skin(w, 3), std::invalid_argument);
    w[0].links = {{0, -0.5f}, {1, 1.5f}};
    EXPECT_THROW(raykit::pack_skin(w, 3), std::invalid_argument);
    w[0].links = {{0, std::nanf("")}};
    EXPECT_THROW(raykit::pack_skin(w, 3), std::invalid_argument);
    w[0].links = {{0, 0.0f}};
    EXPECT_THROW(raykit::pack_skin(w, 3), std::invalid_argument);
    EXPECT_THROW(raykit::pack_skin({}, 70000), std::invalid_argument);
    // Not summing to 1: rescaled. A tiny weight rounds to 0 and is dropped.
    w[0].links = {{0, 2.0f}, {1, 2.0f}, {2, 1e-7f}};
    const raykit::PackedSkin s = raykit::pack_skin(w, 3);
    ASSERT_EQ(s.links.size(), 2u);
    EXPECT_EQ(s.links[0].weight + s.links[1].weight, 65535);
    // A vertex without links stays where it is.
    w[0].links.clear();
    const raykit::PackedSkin e = raykit::pack_skin(w, 3);
    std::vector<raykit::SkinMatrix> mats(3, raykit::to_skin_matrix(glm::dmat4(2.0)));
    const std::vector<vec3> rest{vec3(1, 2, 3)};
    EXPECT_EQ(raykit::skin_positions(e, mats, rest)[0], vec3(1, 2, 3));
    // Mismatched sizes.
    std::vector<vec3> out(2);
    EXPECT_THROW(raykit::skin_vertices(e, mats, rest, {}, out, {}), std::invalid_argument);
    EXPECT_THROW(raykit::skin_vertices(s, std::vector<raykit::SkinMatrix>(2), rest, {}, std::span<vec3>(out).first(1),
                                       {}),
                 std::invalid_argument);
}

TEST(AnimPacked, ParallelSkinningIsDeterministicAndMatchesFloatWeights) {
    // 20 000 synthetic vertices with 1..6 random links over 40 random bones.
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> U(-1.0f, 1.0f);
    const std::size_t nb = 40, nv = 20000;
    std::vector<raykit::SkinMatrix> mats(nb);
    std::vector<glm::dmat4> dm(nb);
    for (std::size_t b = 0; b < nb; ++b) {
        const raykit::BoneTransform t{raykit::euler_xyz_quat({U(rng) * 3, U(rng) * 3, U(rng) * 3}),
                                      glm::dvec3(U(rng), U(rng), U(rng)) * 10.0};
        dm[b] = raykit::transform_matrix(t);
        mats[b] = raykit::to_skin_matrix(dm[b]);
    }
    std::vector<raykit::VertexWeights> w(nv);
    std::vector<vec3> rest(nv), normals(nv);
    for (std::size_t v = 0; v < nv; ++v) {
        const int k = 1 + static_cast<int>(v % 6);
        float sum = 0;
        for (int i = 0; i < k; ++i) {
            const float x = 0.05f + std::abs(U(rng));
            w[v].links.push_back({static_cast<std::uint32_t>((v * 7 + static_cast<std::size_t>(i) * 13) % nb), x});
            sum += x;
        }
        for (auto& l : w[v].links) l.weight /= sum;
        rest[v] = vec3(U(rng), U(rng), U(rng)) * 5.0f;
        normals[v] = glm::normalize(vec3(U(rng), U(rng), U(rng)) + vec3(0.01f));
    }
    const raykit::PackedSkin s = raykit::pack_skin(w, nb);
    std::vector<vec3> p1(nv), n1(nv), p4(nv), n4(nv);
    raykit::skin_vertices(s, mats, rest, normals, p1, n1, 1);
    raykit::skin_vertices(s, mats, rest, normals, p4, n4, 4);
    EXPECT_EQ(std::memcmp(p1.data(), p4.data(), nv * sizeof(vec3)), 0);
    EXPECT_EQ(std::memcmp(n1.data(), n4.data(), nv * sizeof(vec3)), 0);
    // The documented bound of unorm16 weights: a vertex with k links moves by at
    // most k / (2 * 65535) of the spread of its bones' candidate positions.
    double worst_ratio = 0;
    for (std::size_t v = 0; v < nv; ++v) {
        glm::dvec3 p(0.0), n(0.0);
        std::vector<glm::dvec3> cand, cand_n;
        for (const auto& l : w[v].links) {
            cand.push_back(glm::dvec3(dm[l.bone] * glm::dvec4(glm::dvec3(rest[v]), 1.0)));
            cand_n.push_back(glm::dvec3(dm[l.bone] * glm::dvec4(glm::dvec3(normals[v]), 0.0)));
            p += double(l.weight) * cand.back();
            n += double(l.weight) * cand_n.back();
        }
        double spread = 0;
        for (const auto& a : cand)
            for (const auto& b : cand) spread = std::max(spread, glm::length(a - b));
        const double k = static_cast<double>(w[v].links.size());
        const double bound = k / (2 * 65535.0) * spread + 1e-5;
        const double err = glm::length(p - glm::dvec3(p1[v]));
        ASSERT_LE(err, bound) << "vertex " << v;
        worst_ratio = std::max(worst_ratio, (err - 1e-5) / std::max(k / (2 * 65535.0) * spread, 1e-30));
        const double len = glm::length(n);
        if (len > 0.1) {
            ASSERT_LE(glm::length(n / len - glm::dvec3(n1[v])), (k / 65535.0 + 1e-5) / len) << "vertex " << v;
        }
    }
    std::printf("[ info     ] worst position error / documented bound = %.3f\n", worst_ratio);
}

// ------------------------------------------------------------------ skinning vs the oracle

struct Model {
    fs::path ref, anim;
};

void check_model(const Model& mdl, double frame_step, bool print) {
    SCOPED_TRACE(mdl.ref.string());
    const SmdModel m = raykit::load_smd_reference(mdl.ref);
    const SmdSkeletonAnim a = raykit::load_smd_animation(mdl.anim, m);
    const OracleFile oref = oracle_read(mdl.ref), oanim = oracle_read(mdl.anim);
    ASSERT_EQ(oanim.frames.size(), a.frame_count());
    const double extent = extent_of(oref);
    const double tol = 1e-4 * extent;
    // The bind pose first.
    double worst_n = 0;
    const double bind = compare(library_skin(m, nullptr, 0, Interpolation::slerp),
                                oracle_skin(oref, nullptr, 0, true), &worst_n);
    EXPECT_LE(bind, 1e-6 * extent);
    double worst[2] = {0, 0};
    std::size_t samples = 0;
    const double last = static_cast<double>(a.frame_count() - 1);
    for (double f = 0; f <= last; f += frame_step) {
        for (double frame : {f, std::min(f + 0.5, last)}) {
            for (int mode = 0; mode < 2; ++mode) {
                const bool slerp = mode == 0;
                const Posed lib =
                    library_skin(m, &a, frame, slerp ? Interpolation::slerp : Interpolation::euler);
                const double err = compare(lib, oracle_skin(oref, &oanim, frame, slerp), &worst_n);
                ASSERT_LE(err, tol) << "frame " << frame << (slerp ? " slerp" : " euler");
                EXPECT_LE(worst_n, 1e-3) << "normals, frame " << frame;
                worst[mode] = std::max(worst[mode], err);
                ++samples;
            }
        }
    }
    if (print) {
        std::printf("[ info     ] %s: extent %.4g, %zu samples, worst corner error %.3g (slerp) %.3g (euler) = "
                    "%.2g / %.2g of the extent\n",
                    mdl.ref.filename().string().c_str(), extent, samples, worst[0], worst[1], worst[0] / extent,
                    worst[1] / extent);
    }
}

TEST(AnimSkinning, FixtureAgreesWithOracleAtFramesAndHalfFrames) {
    check_model({fixture_dir() / "ref_weights.SMD", fixture_dir() / "anim_weights.smd"}, 0.25, true);
}

/// A scratch folder, removed with its contents at the end of the test.
struct ScratchDir {
    fs::path path;
    ScratchDir() {
        std::random_device rd;
        path = fs::temp_directory_path() / ("raykit_test_anim_" + std::to_string(rd()) + std::to_string(rd()));
        fs::create_directories(path);
    }
    ~ScratchDir() {
        std::error_code ec;
        fs::remove_all(path, ec);
    }
};

/// The fixture animation with its `time` lines renumbered (0, 1, 2, 3 -> the given times).
std::string retimed_fixture_anim(const std::array<int, 4>& times) {
    std::ifstream in(fixture_dir() / "anim_weights.smd", std::ios::binary);
    std::string text, line;
    int k = 0;
    while (std::getline(in, line)) {
        if (line.rfind("time ", 0) == 0) line = "time " + std::to_string(times.at(static_cast<std::size_t>(k++)));
        text += line + "\n";
    }
    return text;
}

TEST(AnimSkinning, GappedAnimationAgreesWithOracle) {
    // Keys at frames 0, 3, 4, 9 (times 5, 8, 9, 14): the oracle spells every frame out.
    ScratchDir dir;
    const fs::path anim = dir.path / "gapped.smd";
    std::ofstream(anim, std::ios::binary) << retimed_fixture_anim({5, 8, 9, 14});
    const SmdModel m = raykit::load_smd_reference(fixture_dir() / "ref_weights.SMD");
    const SmdSkeletonAnim a = raykit::load_smd_animation(anim, m);
    EXPECT_EQ(a.key_count(), 4u);
    EXPECT_EQ(a.frame_count(), 10u);
    check_model({fixture_dir() / "ref_weights.SMD", anim}, 0.25, false);
}

TEST(AnimInterpolate, GapsSampleAsTheSpelledOutFrames) {
    // The same keys stored once (gapped) and as one key per frame (times empty):
    // sample_frame agrees bit for bit, clamped and looping, both schemes.
    const SmdModel m = raykit::load_smd_reference(fixture_dir() / "ref_weights.SMD");
    const SmdSkeletonAnim g =
        raykit::parse_smd_animation(retimed_fixture_anim({0, 3, 4, 9}), "gapped.smd", m.bones, m.bind_pose);
    ASSERT_EQ(g.times, (std::vector<std::uint32_t>{0, 3, 4, 9}));
    SmdSkeletonAnim dense;
    for (std::size_t f = 0; f < g.frame_count(); ++f) dense.frames.push_back(g.frame(f));
    ASSERT_EQ(dense.frame_count(), 10u);
    EXPECT_EQ(dense.frames[2][2].rotation, g.frames[0][2].rotation);  // frame 2 lies in the gap after key 0
    EXPECT_NE(dense.frames[3][2].rotation, g.frames[0][2].rotation);
    for (double f = -2.0; f < 13.0; f += 0.125) {
        for (WrapMode w : {WrapMode::clamp, WrapMode::loop}) {
            for (Interpolation i : {Interpolation::slerp, Interpolation::euler}) {
                const auto x = raykit::sample_frame(g, f, i, w), y = raykit::sample_frame(dense, f, i, w);
                ASSERT_EQ(x.size(), y.size());
                for (std::size_t b = 0; b < x.size(); ++b) {
                    ASSERT_EQ(std::memcmp(&x[b], &y[b], sizeof x[b]), 0) << "frame " << f << " bone " << b;
                }
            }
        }
    }
    // A hand-made animation with inconsistent times is refused, not read out of bounds.
    SmdSkeletonAnim bad = g;
    bad.times.pop_back();
    EXPECT_THROW(raykit::sample_frame(bad, 1.0), std::invalid_argument);
}

TEST(AnimSkinning, DwarfAgreesWithOracleAtFramesAndHalfFrames) {
    const fs::path dir = shared_smd_dir() / "hl1_dwarf";
    if (!fs::exists(dir / "ref.SMD")) GTEST_SKIP() << "shared SMD data not found";
    check_model({dir / "ref.SMD", dir / "run.SMD"}, 1.0, true);
}

TEST(AnimSkinning, GoblinAgreesWithOracleAtFramesAndHalfFrames) {
    const fs::path dir = shared_smd_dir() / "hl2_goblin";
    if (!fs::exists(dir / "Goblin_Reference.smd")) GTEST_SKIP() << "shared SMD data not found";
    check_model({dir / "Goblin_Reference.smd", dir / "Goblin_Anim.smd"}, 7.0, true);
}

// ------------------------------------------------------------------ the CLI command

raykit_cli::SkinArgs parse_args(std::vector<std::string> a) {
    a.insert(a.begin(), {"raykit", "skin"});
    std::vector<char*> argv;
    for (std::string& s : a) argv.push_back(s.data());
    return raykit_cli::parse_skin_args(static_cast<int>(argv.size()), argv.data(), 2);
}

TEST(AnimCli, Arguments) {
    auto a = parse_args({"ref.smd"});
    EXPECT_EQ(a.reference, "ref.smd");
    EXPECT_TRUE(a.animation.empty());
    a = parse_args({"--interp", "euler", "ref.smd", "run.smd", "2.5", "--device", "cpu"});
    EXPECT_EQ(a.animation, "run.smd");
    EXPECT_EQ(a.frame, 2.5);
    EXPECT_EQ(a.interp, Interpolation::euler);
    using E = raykit_cli::SkinUsageError;
    EXPECT_THROW(parse_args({}), E);
    EXPECT_THROW(parse_args({"ref.smd", "run.smd"}), E);
    EXPECT_THROW(parse_args({"ref.smd", "run.smd", "x"}), E);
    EXPECT_THROW(parse_args({"ref.smd", "run.smd", "-1"}), E);
    EXPECT_THROW(parse_args({"ref.smd", "run.smd", "nan"}), E);
    EXPECT_THROW(parse_args({"ref.smd", "--interp"}), E);
    EXPECT_THROW(parse_args({"ref.smd", "--interp", "cubic"}), E);
    EXPECT_THROW(parse_args({"ref.smd", "--device", "gpu"}), E);
    EXPECT_THROW(parse_args({"ref.smd", "--fast"}), E);
}

TEST(AnimCli, PrintsEveryCornerInFileOrder) {
    raykit_cli::SkinArgs a;
    a.reference = (fixture_dir() / "ref_weights.SMD").string();
    a.animation = (fixture_dir() / "anim_weights.smd").string();
    a.frame = 2.5;
    std::vector<std::string> warnings;
    const std::string text = raykit_cli::skin_corners_text(a, &warnings);
    EXPECT_EQ(warnings.size(), 2u);  // missing texture, unknown bone 'camera'
    const OracleFile oref = oracle_read(a.reference), oanim = oracle_read(a.animation);
    const OracleSkin o = oracle_skin(oref, &oanim, 2.5, true);
    std::istringstream in(text);
    std::string line;
    std::size_t i = 0;
    while (std::getline(in, line)) {
        ASSERT_LT(i, o.pos.size());
        V3 p{};
        std::istringstream(line) >> p[0] >> p[1] >> p[2];
        EXPECT_LT(dist(p, o.pos[i]), 1e-4 * extent_of(oref)) << "corner " << i << ": " << line;
        ++i;
    }
    EXPECT_EQ(i, o.pos.size());
    a.frame = 3.5;
    EXPECT_THROW(raykit_cli::skin_corners_text(a, nullptr), std::runtime_error);
    a.frame = 3.0;
    EXPECT_NO_THROW(raykit_cli::skin_corners_text(a, nullptr));
    a.animation = (fixture_dir() / "absent.smd").string();
    EXPECT_THROW(raykit_cli::skin_corners_text(a, nullptr), raykit::ParseError);
}

TEST(AnimCli, BindPoseReproducesTheFile) {
    const fs::path tri = "/usr/share/assimp/models/SMD/triangle.smd";
    if (!fs::exists(tri)) GTEST_SKIP() << tri << " not found";
    raykit_cli::SkinArgs a;
    a.reference = tri.string();
    EXPECT_EQ(raykit_cli::skin_corners_text(a, nullptr), "0 0 0\n1 0 0\n1 1 0\n");
}

raykit_cli::AnimateArgs animate_args(std::vector<std::string> a) {
    a.insert(a.begin(), {"raykit", "animate"});
    std::vector<char*> argv;
    for (std::string& x : a) argv.push_back(x.data());
    return raykit_cli::parse_animate_args(static_cast<int>(argv.size()), argv.data(), 2);
}

TEST(AnimateCli, OutputPatternGivesEveryFrameItsOwnName) {
    using raykit_cli::animate_frame_name;
    EXPECT_EQ(animate_frame_name("out_%03d.png", 7), "out_007.png");
    EXPECT_EQ(animate_frame_name("out_%d.png", 1234), "out_1234.png");
    EXPECT_EQ(animate_frame_name("out_%4d.png", 12), "out_  12.png");
    EXPECT_EQ(animate_frame_name("%0003d", 5), "005");
    EXPECT_EQ(animate_frame_name("f%032d", 9), "f" + std::string(31, '0') + "9");
    EXPECT_EQ(animate_frame_name("still.png", 3), "still.png");
    // Every accepted pattern names frames 0..N distinctly (no truncation).
    for (const char* p : {"a%d", "a%1d", "a%05d", "a%32d", "a%032d", "%d.png"}) {
        std::set<std::string> names;
        for (long k : {0L, 1L, 9L, 10L, 99L, 100L, 12345L, 999999999L, 1000000000L, 2147483647L, 9999999999L}) {
            names.insert(animate_frame_name(p, k));
        }
        EXPECT_EQ(names.size(), 11u) << p;
    }
    using E = RaykitCliAnimateUsageError;
    EXPECT_THROW(animate_frame_name("out_%3000000000d.png", 0), E);  // one name for every frame before
    EXPECT_THROW(animate_frame_name("out_%33d.png", 0), E);
    EXPECT_THROW(animate_frame_name("out_%0100d.png", 0), E);
    EXPECT_THROW(animate_frame_name("out_%s.png", 0), E);
    EXPECT_THROW(animate_frame_name("out_%-3d.png", 0), E);
    EXPECT_THROW(animate_frame_name("out_%3.2d.png", 0), E);
    EXPECT_THROW(animate_frame_name("out_%d_%d.png", 0), E);
    EXPECT_THROW(animate_frame_name("100%_%d.png", 0), E);
    EXPECT_THROW(animate_frame_name("out_%", 0), E);
    try {
        animate_frame_name("out_%3000000000d.png", 0);
    } catch (const E& e) {
        EXPECT_NE(std::string(e.what()).find("field width 3000000000 is too large"), std::string::npos) << e.what();
    }
    // The arguments are checked when parsed.
    EXPECT_THROW(animate_args({"r.smd", "a.smd", "out_%3000000000d.png"}), E);
    EXPECT_THROW(animate_args({"r.smd", "a.smd", "out.png", "--frames", "2"}), E);
    EXPECT_NO_THROW(animate_args({"r.smd", "a.smd", "out.png", "--frames", "1"}));
    EXPECT_EQ(animate_args({"r.smd", "a.smd", "o_%02d.png", "--frames", "3"}).output, "o_%02d.png");
}

// The flags animate shares with render have render's ranges (issue 12: --threads 5000 was
// accepted, 1e9 x 1e9 images asked for exabytes).
TEST(AnimateCli, SharedFlagsHaveRendersRanges) {
    using E = RaykitCliAnimateUsageError;
    auto with = [](std::vector<std::string> extra) {
        std::vector<std::string> a = {"r.smd", "a.smd", "o_%02d.png"};
        a.insert(a.end(), extra.begin(), extra.end());
        return animate_args(a);
    };
    EXPECT_EQ(with({"--threads", "1024"}).threads, 1024u);
    EXPECT_THROW(with({"--threads", "1025"}), E);
    EXPECT_THROW(with({"--threads", "4294967296"}), E);
    EXPECT_EQ(with({"--width", "65536", "--height", "256"}).width, 65536u);
    EXPECT_THROW(with({"--width", "65537"}), E);
    EXPECT_THROW(with({"--width", "65536", "--height", "65536"}), E);  // over 2^24 pixels
    EXPECT_THROW(with({"--spp", "65537"}), E);
    EXPECT_THROW(with({"--max-depth", "1001"}), E);
}

}  // namespace
