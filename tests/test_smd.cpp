// Tests for raykit/io/smd.hpp: hand-written fixtures (tests/data/smd) for the
// weight rules, bone order and retargeting; every malformed-input rule with
// its line; and every real SMD under <repo>/../shared/data/smd and
// /usr/share/assimp/models/SMD, checked against a small independent reader
// written in this file (istringstream based, its own weight rule) — including
// that the skinned bind pose reproduces each file's vertices.
#include "raykit/io/smd.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "raykit/anim/skeleton.hpp"
#include "raykit/anim/skinning.hpp"
#include "test_text.hpp"

namespace fs = std::filesystem;
using raykit::BonePose;
using raykit::ParseError;
using raykit::SmdModel;
using raykit::SmdSkeletonAnim;
using raykit::vec3;

namespace {

// ------------------------------------------------------------------ helpers

constexpr const char* kName = "fixture.smd";

fs::path fixture_dir() { return fs::path(RAYKIT_TEST_DATA_DIR) / "smd"; }

fs::path shared_smd_dir() {
#ifdef RAYKIT_SHARED_DATA_DIR
    return fs::path(RAYKIT_SHARED_DATA_DIR) / "smd";
#else
    return fs::path(__FILE__).parent_path().parent_path().parent_path() / "shared" / "data" / "smd";
#endif
}

const fs::path kAssimpSmdDir = "/usr/share/assimp/models/SMD";

std::string join_lines(const std::vector<std::string>& lines) {
    std::string s;
    for (const std::string& l : lines) s += l + "\n";
    return s;
}

SmdModel parse_ref(std::string_view text, const fs::path& base = {}) {
    return raykit::parse_smd_reference(text, kName, base);
}

template <class F>
std::optional<ParseError> error_of(F&& f) {
    try {
        f();
    } catch (const ParseError& e) {
        return e;
    }
    return std::nullopt;
}

template <class F>
void expect_error(F&& f, const std::string& file, std::size_t line, const std::string& fragment) {
    const std::optional<ParseError> e = error_of(f);
    ASSERT_TRUE(e.has_value()) << "no ParseError thrown";
    EXPECT_EQ(e->file(), file);
    EXPECT_EQ(e->line(), line) << e->what();
    const std::string what = e->what();
    // an error tied to no line reads "FILE: ..." (ParseError), others "FILE:LINE: ..."
    const std::string prefix = line == 0 ? file + ": " : file + ":" + std::to_string(line) + ": ";
    EXPECT_EQ(what.rfind(prefix, 0), 0u) << what;
    EXPECT_NE(what.find(fragment), std::string::npos) << "'" << fragment << "' not in: " << what;
}

/// A scratch folder, removed with its contents at the end of the test.
class TempDir {
public:
    TempDir() {
        std::random_device rd;
        path_ = fs::temp_directory_path() / ("raykit_test_smd_" + std::to_string(rd()) + std::to_string(rd()));
        fs::create_directories(path_);
    }
    ~TempDir() {
        std::error_code ec;
        fs::remove_all(path_, ec);
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;
    const fs::path& path() const { return path_; }
    fs::path write(const std::string& name, const std::string& text) const {
        const fs::path p = path_ / name;
        std::ofstream(p, std::ios::binary) << text;
        return p;
    }

private:
    fs::path path_;
};

// ------------------------------------------------------------------ independent reader (the oracle)
//
// Reads the triangles of an SMD with std::istringstream, one corner per
// vertex line, and applies Valve's weight rule in its own way (a std::map of
// bone -> weight). It knows nothing of the loader's de-duplication.

struct OracleCorner {
    std::array<double, 3> pos{};
    std::array<double, 3> nrm{};
    std::array<double, 2> uv{};
    std::map<int, double> weights;  // bone -> weight, sum 1
};

struct OracleMesh {
    std::vector<std::string> materials;  // per triangle
    std::vector<OracleCorner> corners;   // 3 per triangle, file order
    int bone_count = 0;
};

std::string strip_cr(std::string s) {
    while (!s.empty() && (s.back() == '\r' || s.back() == ' ' || s.back() == '\t')) s.pop_back();
    std::size_t b = 0;
    while (b < s.size() && (s[b] == ' ' || s[b] == '\t')) ++b;
    return s.substr(b);
}

OracleMesh oracle_read(const fs::path& file) {
    std::ifstream in(file, std::ios::binary);
    OracleMesh m;
    std::string line;
    enum { top, nodes, skel, tris } state = top;
    int corner = -1;
    while (std::getline(in, line)) {
        line = strip_cr(line);
        if (line.empty() || line.rfind("//", 0) == 0) continue;
        if (state == top) {
            if (line == "nodes") state = nodes;
            if (line == "skeleton") state = skel;
            if (line == "triangles") state = tris;
            continue;
        }
        if (line == "end" && corner < 0) {
            state = top;
            continue;
        }
        if (state == nodes) {
            ++m.bone_count;
        } else if (state == tris) {
            if (corner < 0) {
                m.materials.push_back(line);
                corner = 0;
                continue;
            }
            std::istringstream s(line);
            OracleCorner c;
            int parent = 0, links = 0;
            s >> parent >> c.pos[0] >> c.pos[1] >> c.pos[2] >> c.nrm[0] >> c.nrm[1] >> c.nrm[2] >> c.uv[0] >> c.uv[1];
            double given = 0.0;
            if (s >> links) {
                for (int k = 0; k < links; ++k) {
                    int b = 0;
                    double w = 0.0;
                    s >> b >> w;
                    c.weights[b] += w;
                    given += w;
                }
            }
            if (links == 0) {
                c.weights = {{parent, 1.0}};
            } else {
                if (1.0 - given > 1e-5) {
                    c.weights[parent] += 1.0 - given;
                    given = 1.0;
                }
                for (auto it = c.weights.begin(); it != c.weights.end();) {
                    if (it->second <= 0.0) {
                        it = c.weights.erase(it);
                    } else {
                        it->second /= given;
                        ++it;
                    }
                }
            }
            m.corners.push_back(c);
            if (++corner == 3) corner = -1;
        }
    }
    return m;
}

double extent_of(const std::vector<OracleCorner>& corners) {
    std::array<double, 3> lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    for (const OracleCorner& c : corners) {
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], c.pos[k]);
            hi[k] = std::max(hi[k], c.pos[k]);
        }
    }
    return std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                     (hi[2] - lo[2]) * (hi[2] - lo[2]));
}

std::vector<vec3> skin_bind_pose(const SmdModel& m) {
    const raykit::Skeleton sk(m);
    const auto mats = raykit::skin_matrices(sk, sk.bind_transforms());
    const auto packed = raykit::pack_skin(m.weights, m.bones.size());
    return raykit::skin_positions(packed, mats, m.mesh.positions, 1);
}

/// Checks a loaded reference against the oracle corner by corner: position,
/// normal, uv, weights, material, and that the skinned bind pose gives the
/// file's positions back.
void check_against_oracle(const fs::path& file) {
    SCOPED_TRACE(file.string());
    const SmdModel m = raykit::load_smd_reference(file);
    const OracleMesh o = oracle_read(file);
    ASSERT_EQ(m.bones.size(), static_cast<std::size_t>(o.bone_count));
    ASSERT_EQ(m.mesh.triangles.size() * 3, o.corners.size());
    ASSERT_EQ(m.mesh.material_ids.size(), m.mesh.triangles.size());
    ASSERT_EQ(m.weights.size(), m.mesh.positions.size());
    ASSERT_EQ(m.mesh.normals.size(), m.mesh.positions.size());
    ASSERT_EQ(m.mesh.texcoords.size(), m.mesh.positions.size());
    const std::vector<vec3> bind = skin_bind_pose(m);
    const double extent = extent_of(o.corners);
    double worst_bind = 0.0;
    for (std::size_t t = 0; t < m.mesh.triangles.size(); ++t) {
        ASSERT_EQ(m.mesh.materials.at(m.mesh.material_ids[t]).name, o.materials[t]);
        for (int c = 0; c < 3; ++c) {
            const std::uint32_t v = m.mesh.triangles[t].v[c];
            const OracleCorner& oc = o.corners[3 * t + static_cast<std::size_t>(c)];
            for (int k = 0; k < 3; ++k) {
                ASSERT_EQ(m.mesh.positions[v][k], static_cast<float>(oc.pos[k])) << "triangle " << t;
                ASSERT_EQ(m.mesh.normals[v][k], static_cast<float>(oc.nrm[k])) << "triangle " << t;
                worst_bind = std::max(worst_bind, std::abs(double(bind[v][k]) - oc.pos[k]));
            }
            for (int k = 0; k < 2; ++k) ASSERT_EQ(m.mesh.texcoords[v][k], static_cast<float>(oc.uv[k]));
            std::map<int, double> got;
            for (const raykit::BoneWeight& l : m.weights[v].links) {
                ASSERT_EQ(got.count(static_cast<int>(l.bone)), 0u) << "bone listed twice";
                got[static_cast<int>(l.bone)] = l.weight;
            }
            ASSERT_EQ(got.size(), oc.weights.size()) << "triangle " << t << " corner " << c;
            for (const auto& [b, w] : oc.weights) {
                ASSERT_EQ(got.count(b), 1u) << "bone " << b;
                EXPECT_NEAR(got[b], w, 1e-6);
            }
        }
    }
    // The bind pose reproduces the file's vertices (float rounding of matrices
    // that are the identity in exact arithmetic).
    EXPECT_LE(worst_bind, 1e-6 * std::max(extent, 1.0)) << "extent " << extent;
}

// ------------------------------------------------------------------ fixtures

TEST(SmdFixture, BonesInAnyOrderTwoRootsAndBindPose) {
    const SmdModel m = raykit::load_smd_reference(fixture_dir() / "ref_weights.SMD");
    ASSERT_EQ(m.bones.size(), 4u);
    const std::vector<std::pair<std::string, int>> bones = {{"hips", -1}, {"torso", 0}, {"arm", 1}, {"prop", -1}};
    for (std::size_t i = 0; i < 4; ++i) {
        EXPECT_EQ(m.bones[i].name, bones[i].first);
        EXPECT_EQ(m.bones[i].parent, bones[i].second);
    }
    ASSERT_EQ(m.bind_pose.size(), 4u);
    EXPECT_EQ(m.bind_pose[0].position, vec3(0, 0, 1));
    EXPECT_EQ(m.bind_pose[1].rotation, vec3(0, 0, 1.570796f));
    EXPECT_EQ(m.bind_pose[2].position, vec3(1, 0, 0));
    EXPECT_EQ(m.bind_pose[3].position, vec3(5, 0, 0));
    EXPECT_EQ(m.bind_pose[3].rotation, vec3(1.570796f, 0, 0));
}

TEST(SmdFixture, WeightRules) {
    const SmdModel m = raykit::load_smd_reference(fixture_dir() / "ref_weights.SMD");
    // Corners in file order -> expected links (bone, weight), hand-computed.
    using L = std::vector<std::pair<std::uint32_t, float>>;
    const std::vector<L> expected = {
        {{1, 0.6f}, {2, 0.4f}},              // 0.6 / 0.4
        {{0, 0.4f}, {1, 0.3f}, {2, 0.3f}},   // 0.4 / 0.3 / 0.3
        {{2, 0.5f}, {3, 0.4f}, {0, 0.1f}},   // sum 0.9: remainder 0.1 to the parent (bone 0)
        {{3, 1.0f}},                         // Half-Life 1 line: wholly the parent
        {{3, 1.0f}},                         // link count 0: wholly the parent
        {{2, 1.0f}},                         // bone 2 listed twice: 0.5 + 0.5
        {{1, 0.6f}, {2, 0.4f}},              // = corner 0
        {{1, 0.6f}, {2, 0.4f}},              // = corner 0 (other parent field, same weights)
        {{2, 1.0f}},
        {{0, 1.0f}},
        {{1, 1.0f}},
        {{2, 0.25f}, {1, 0.75f}},
    };
    ASSERT_EQ(m.mesh.triangles.size(), 4u);
    for (std::size_t i = 0; i < expected.size(); ++i) {
        SCOPED_TRACE("corner " + std::to_string(i));
        const auto& links = m.weights[m.mesh.triangles[i / 3].v[i % 3]].links;
        ASSERT_EQ(links.size(), expected[i].size());
        for (std::size_t k = 0; k < links.size(); ++k) {
            EXPECT_EQ(links[k].bone, expected[i][k].first);
            EXPECT_NEAR(links[k].weight, expected[i][k].second, 1e-6f);
        }
    }
}

TEST(SmdFixture, VerticesDeduplicatedPerPositionNormalUvWeights) {
    const SmdModel m = raykit::load_smd_reference(fixture_dir() / "ref_weights.SMD");
    // 12 corners; corners 6 and 7 repeat corner 0 (same position, normal, uv
    // and weights; corner 7 has another parent field but the same weights).
    ASSERT_EQ(m.mesh.positions.size(), 10u);
    EXPECT_EQ(m.mesh.triangles[2].v[0], m.mesh.triangles[0].v[0]);
    EXPECT_EQ(m.mesh.triangles[2].v[1], m.mesh.triangles[0].v[0]);
    const std::vector<std::array<std::uint32_t, 3>> tris = {{0, 1, 2}, {3, 4, 5}, {0, 0, 6}, {7, 8, 9}};
    for (std::size_t t = 0; t < 4; ++t) {
        for (int c = 0; c < 3; ++c) EXPECT_EQ(m.mesh.triangles[t].v[c], tris[t][static_cast<std::size_t>(c)]);
    }
    EXPECT_EQ(m.mesh.positions[3], vec3(5.0f, 0.0f, 0.5f));
    EXPECT_EQ(m.mesh.normals[3], vec3(0.0f, 1.0f, 0.0f));
    EXPECT_EQ(m.mesh.texcoords[3], raykit::vec2(0.5f, 0.5f));
}

TEST(SmdFixture, MaterialsResolveNextToTheFile) {
    const SmdModel m = raykit::load_smd_reference(fixture_dir() / "ref_weights.SMD");
    ASSERT_EQ(m.mesh.materials.size(), 3u);
    EXPECT_EQ(m.mesh.material_ids, (std::vector<std::uint32_t>{0, 1, 0, 2}));
    EXPECT_EQ(m.mesh.materials[0].name, "Skin.BMP");
    EXPECT_EQ(fs::path(m.mesh.materials[0].map_kd), fixture_dir() / "skin.bmp");  // case-insensitive
    EXPECT_EQ(m.mesh.materials[1].name, "prop");
    EXPECT_EQ(fs::path(m.mesh.materials[1].map_kd), fixture_dir() / "prop.BMP");  // extension added
    EXPECT_EQ(m.mesh.materials[2].name, "missing.bmp");
    EXPECT_EQ(fs::path(m.mesh.materials[2].map_kd), fixture_dir() / "missing.bmp");
    ASSERT_EQ(m.mesh.warnings.size(), 1u);
    EXPECT_NE(m.mesh.warnings[0].find("ref_weights.SMD:31: texture 'missing.bmp' not found"), std::string::npos)
        << m.mesh.warnings[0];
}

TEST(SmdFixture, AgreesWithIndependentReader) { check_against_oracle(fixture_dir() / "ref_weights.SMD"); }

TEST(SmdFixture, AnimationRetargetedByName) {
    const SmdModel ref = raykit::load_smd_reference(fixture_dir() / "ref_weights.SMD");
    const SmdSkeletonAnim a = raykit::load_smd_animation(fixture_dir() / "anim_weights.smd", ref);
    ASSERT_EQ(a.frames.size(), 4u);
    EXPECT_EQ(a.fps, 30.0f);
    for (const auto& f : a.frames) ASSERT_EQ(f.size(), 4u);
    // reference ids: hips 0, torso 1, arm 2, prop 3 (file ids: hips 1, torso 2, arm 3)
    EXPECT_EQ(a.frames[0][0].position, vec3(0, 0, 1));
    EXPECT_EQ(a.frames[0][1].rotation, vec3(0, 0, 1.570796f));
    EXPECT_EQ(a.frames[0][2].rotation, vec3(0, 0, 3.0f));
    EXPECT_EQ(a.frames[1][2].rotation, vec3(0, 0, -3.0f));
    EXPECT_EQ(a.frames[3][2].rotation, vec3(1.570796f, 1.570796f, 0));
    // Absent from frames 1-3: keeps its frame-0 value; hips moves at frame 2.
    for (int f = 1; f < 4; ++f) EXPECT_EQ(a.frames[f][1].rotation, vec3(0, 0, 1.570796f));
    EXPECT_EQ(a.frames[1][0].position, vec3(0, 0, 1));
    EXPECT_EQ(a.frames[2][0].position, vec3(0, 0.5f, 1));
    EXPECT_EQ(a.frames[3][0].position, vec3(0, 0.5f, 1));
    // prop is never animated: the reference's bind pose.
    for (int f = 0; f < 4; ++f) {
        EXPECT_EQ(a.frames[f][3].position, ref.bind_pose[3].position);
        EXPECT_EQ(a.frames[f][3].rotation, ref.bind_pose[3].rotation);
    }
    ASSERT_EQ(a.warnings.size(), 1u);
    EXPECT_NE(a.warnings[0].find(":8: bone 'camera' is not in the reference"), std::string::npos) << a.warnings[0];

    // Without a rest pose an un-animated bone gets the zero pose.
    const SmdSkeletonAnim z = raykit::load_smd_animation(fixture_dir() / "anim_weights.smd", ref.bones);
    EXPECT_EQ(z.frames[2][3].position, vec3(0.0f));
    EXPECT_EQ(z.frames[2][3].rotation, vec3(0.0f));
    // A rest pose of the wrong length is a programming error.
    EXPECT_THROW(raykit::load_smd_animation(fixture_dir() / "anim_weights.smd", ref.bones,
                                            std::vector<BonePose>(2)),
                 std::invalid_argument);
}

TEST(SmdFixture, AnimationParentMismatchWarns) {
    const SmdModel ref = raykit::load_smd_reference(fixture_dir() / "ref_weights.SMD");
    const std::string text = join_lines({"version 1", "nodes", "0 \"hips\" -1", "1 \"arm\" 0", "end", "skeleton",
                                         "time 0", "0 0 0 0 0 0 0", "end"});
    const SmdSkeletonAnim a = raykit::parse_smd_animation(text, kName, ref.bones, ref.bind_pose);
    ASSERT_EQ(a.warnings.size(), 1u);
    EXPECT_NE(a.warnings[0].find("fixture.smd:4: bone 'arm' has parent 'hips' here but 'torso'"), std::string::npos)
        << a.warnings[0];
    EXPECT_EQ(a.frames[0][2].position, ref.bind_pose[2].position);  // absent from the first frame: rest pose
}

// ------------------------------------------------------------------ lexical and structural rules

const std::vector<std::string> kBase = {
    "version 1",                              // 1
    "nodes",                                  // 2
    "0 \"root\" -1",                          // 3
    "1 \"child\" 0",                          // 4
    "end",                                    // 5
    "skeleton",                               // 6
    "time 0",                                 // 7
    "0 0 0 0 0 0 0",                          // 8
    "1 1 0 0 0 0 0",                          // 9
    "end",                                    // 10
    "triangles",                              // 11
    "tex.bmp",                                // 12
    "0 0 0 0 0 0 1 0 0",                      // 13
    "1 1 0 0 0 0 1 1 0",                      // 14
    "0 0 1 0 0 0 1 0 1 2 0 0.5 1 0.5",        // 15
    "end",                                    // 16
};

std::vector<std::string> with(std::vector<std::string> lines, std::size_t line, const std::string& text) {
    lines.at(line - 1) = text;
    return lines;
}
std::vector<std::string> without(std::vector<std::string> lines, std::size_t line) {
    lines.erase(lines.begin() + static_cast<std::ptrdiff_t>(line - 1));
    return lines;
}
std::vector<std::string> inserted(std::vector<std::string> lines, std::size_t line, const std::string& text) {
    lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(line - 1), text);
    return lines;
}
std::vector<std::string> first_lines(const std::vector<std::string>& lines, std::size_t n) {
    return {lines.begin(), lines.begin() + static_cast<std::ptrdiff_t>(n)};
}

TEST(SmdParse, BaseFixtureIsValid) {
    const SmdModel m = parse_ref(join_lines(kBase));
    EXPECT_EQ(m.bones.size(), 2u);
    EXPECT_EQ(m.mesh.triangles.size(), 1u);
    EXPECT_EQ(m.mesh.positions.size(), 3u);
    ASSERT_EQ(m.weights[2].links.size(), 2u);
    EXPECT_EQ(m.bind_pose[1].position, vec3(1, 0, 0));
}

TEST(SmdParse, CrlfBomCommentsBlankLinesAndNoFinalNewline) {
    std::string text = "\xEF\xBB\xBF";
    for (std::size_t i = 0; i < kBase.size(); ++i) {
        text += kBase[i];
        if (i + 1 < kBase.size()) text += "\r\n";
        if (i == 5) text += "// a comment\r\n\r\n  \t\r\n# another\r\n; and another\r\n";
    }
    const SmdModel m = parse_ref(text);
    EXPECT_EQ(m.mesh.triangles.size(), 1u);
    EXPECT_EQ(m.bind_pose[1].position, vec3(1, 0, 0));
    // Line numbers count the skipped lines.
    std::string bad = text;
    bad.replace(bad.find("1 1 0 0 0 0 1 1 0"), 17, "1 1 0 0 0 0 1 1 x");
    expect_error([&] { parse_ref(bad); }, kName, 19, "malformed number 'x'");
}

TEST(SmdParse, ByteOrderMarksAndUtf16AsInObj) {
    // io/lexer.hpp's one rule for every reader: a UTF-8 BOM is skipped, UTF-16 with a BOM converted
    const std::string name = "caf\xC3\xA9 \xF0\x9F\x98\x80";  // U+00E9 and U+1F600 (a surrogate pair)
    const std::vector<std::string> lines = with(kBase, 4, "1 \"" + name + "\" 0");
    const std::string text = join_lines(lines);
    const SmdModel plain = parse_ref(text);
    auto expect_plain = [&](const SmdModel& m) {
        ASSERT_EQ(m.bones.size(), 2u);
        EXPECT_EQ(m.bones[1].name, name);
        EXPECT_EQ(m.bind_pose[1].position, plain.bind_pose[1].position);
        EXPECT_EQ(m.mesh.positions, plain.mesh.positions);
        EXPECT_EQ(m.mesh.triangles.size(), plain.mesh.triangles.size());
    };
    {
        SCOPED_TRACE("UTF-8 BOM");
        expect_plain(parse_ref("\xEF\xBB\xBF" + text));
    }
    const std::string anim_text = join_lines(first_lines(with(lines, 9, "1 2 0 0 0 0 0"), 10));
    for (bool big : {true, false}) {
        SCOPED_TRACE(big ? "UTF-16BE" : "UTF-16LE");
        expect_plain(parse_ref(raykit::test::utf16_with_bom(text, big)));
        // an animation retargets by the decoded bone name
        const SmdSkeletonAnim a =
            raykit::parse_smd_animation(raykit::test::utf16_with_bom(anim_text, big), kName, plain.bones);
        EXPECT_TRUE(a.warnings.empty());
        ASSERT_EQ(a.key_count(), 1u);
        EXPECT_EQ(a.frame(0)[1].position, vec3(2, 0, 0));
        // errors name the text's line
        expect_error([&] { parse_ref(raykit::test::utf16_with_bom(join_lines(with(lines, 14, "1 1 0 0 0 0 1 1 x")), big)); },
                     kName, 14, "malformed number 'x'");
    }
    expect_error([] { parse_ref(std::string("\xFF\xFE\x76", 3)); }, kName, 0, "UTF-16");
}

TEST(SmdParse, VersionIsOptionalAndVertexAnimationIsSkipped) {
    auto lines = without(kBase, 1);
    lines.insert(lines.end(), {"vertexanimation", "time 0", "0 1 2 3 4 5 6", "end"});
    const SmdModel m = parse_ref(join_lines(lines));
    EXPECT_EQ(m.mesh.triangles.size(), 1u);
}

TEST(SmdParse, NoTrianglesGivesAnEmptyMesh) {
    const SmdModel m = parse_ref(join_lines(first_lines(kBase, 10)));
    EXPECT_TRUE(m.mesh.triangles.empty());
    EXPECT_TRUE(m.mesh.positions.empty());
    EXPECT_EQ(m.bones.size(), 2u);
}

TEST(SmdParse, UnquotedNamesAndNamesWithSpaces) {
    auto lines = with(kBase, 3, "0 \"Bip01 L Thigh\" -1");
    lines = with(lines, 4, "1 child 0");
    const SmdModel m = parse_ref(join_lines(lines));
    EXPECT_EQ(m.bones[0].name, "Bip01 L Thigh");
    EXPECT_EQ(m.bones[1].name, "child");
}

TEST(SmdParse, BoneAbsentFromTheFirstFrameWarnsAndIsZero) {
    const SmdModel m = parse_ref(join_lines(without(kBase, 9)));
    EXPECT_EQ(m.bind_pose[1].position, vec3(0.0f));
    ASSERT_EQ(m.mesh.warnings.size(), 2u);  // + the missing texture
    EXPECT_NE(m.mesh.warnings[0].find("fixture.smd:7: bone 1 'child' has no pose in the first frame"),
              std::string::npos)
        << m.mesh.warnings[0];
}

TEST(SmdParse, TimeGapsRepeatTheLastFrame) {
    const std::string text = join_lines({"nodes", "0 \"a\" -1", "1 \"b\" 0", "end", "skeleton", "time 2",
                                         "0 1 0 0 0 0 0", "1 2 0 0 0 0 0", "time 3", "0 3 0 0 0 0 0", "time 6",
                                         "1 4 0 0 0 0 0", "end"});
    const SmdModel ref = parse_ref(text);
    EXPECT_EQ(ref.bind_pose[0].position.x, 1.0f);
    const SmdSkeletonAnim a = raykit::parse_smd_animation(text, kName, ref.bones);
    // Three keys (one per `time` line) at frames 0, 1, 4; the animation spans frames 0..4 (times 2..6).
    ASSERT_EQ(a.frames.size(), 3u);
    EXPECT_EQ(a.times, (std::vector<std::uint32_t>{0, 1, 4}));
    ASSERT_EQ(a.frame_count(), 5u);
    const float expect_a[5] = {1, 3, 3, 3, 3};
    const float expect_b[5] = {2, 2, 2, 2, 4};
    const std::size_t expect_key[5] = {0, 1, 1, 1, 2};
    for (std::size_t f = 0; f < 5; ++f) {
        EXPECT_EQ(a.key_of_frame(f), expect_key[f]) << f;
        EXPECT_EQ(a.frame(f)[0].position.x, expect_a[f]) << f;
        EXPECT_EQ(a.frame(f)[1].position.x, expect_b[f]) << f;
    }
    EXPECT_THROW((void)a.frame(5), std::out_of_range);
}

TEST(SmdParse, GapsCostNothingAndMatchTheSpelledOutFile) {
    // Key frames at times 0, 2e9 and 2e9 + 3: three keys however long the gaps.
    const std::vector<std::string> head = {"nodes", "0 \"a\" -1", "1 \"b\" 0", "end", "skeleton"};
    auto lines = head;
    lines.insert(lines.end(), {"time 5", "0 1 0 0 0 0 0.5", "time 2000000005", "1 0 2 0 0 0 -1", "time 2000000008",
                               "0 3 0 0 0.25 0 0", "end"});
    const SmdModel ref = parse_ref(join_lines(head) + "time 0\n0 0 0 0 0 0 0\n1 0 0 0 0 0 0\nend\n");
    const SmdSkeletonAnim a = raykit::parse_smd_animation(join_lines(lines), kName, ref.bones, ref.bind_pose);
    EXPECT_EQ(a.frame_count(), 2000000004u);
    EXPECT_EQ(a.key_count(), 3u);
    EXPECT_EQ(a.times, (std::vector<std::uint32_t>{0, 2000000000u, 2000000003u}));
    EXPECT_EQ(a.frame(1999999999)[0].position.x, 1.0f);
    EXPECT_EQ(a.frame(2000000000)[1].position.y, 2.0f);
    EXPECT_EQ(a.frame(2000000002)[1].position.y, 2.0f);
    EXPECT_EQ(a.frame(2000000003)[0].position.x, 3.0f);

    // A short gapped file equals, frame by frame, the file that spells every frame out.
    auto gapped = head, spelled = head;
    gapped.insert(gapped.end(), {"time 1", "0 1 0 0 0 0 0.5", "1 0 1 0 0.5 0 0", "time 4", "0 2 0 0 0 0 -3",
                                 "time 5", "time 7", "1 0 3 0 -0.5 1 0", "end"});
    spelled.insert(spelled.end(), {"time 1", "0 1 0 0 0 0 0.5", "1 0 1 0 0.5 0 0", "time 2", "time 3", "time 4",
                                   "0 2 0 0 0 0 -3", "time 5", "time 6", "time 7", "1 0 3 0 -0.5 1 0", "end"});
    const SmdSkeletonAnim g = raykit::parse_smd_animation(join_lines(gapped), kName, ref.bones, ref.bind_pose);
    const SmdSkeletonAnim s = raykit::parse_smd_animation(join_lines(spelled), kName, ref.bones, ref.bind_pose);
    EXPECT_EQ(g.key_count(), 4u);
    ASSERT_EQ(s.key_count(), 7u);
    EXPECT_EQ(s.times, (std::vector<std::uint32_t>{0, 1, 2, 3, 4, 5, 6}));
    ASSERT_EQ(g.frame_count(), s.frame_count());
    for (std::size_t f = 0; f < s.frame_count(); ++f) {
        for (std::size_t b = 0; b < 2; ++b) {
            EXPECT_EQ(g.frame(f)[b].position, s.frames[f][b].position) << f;
            EXPECT_EQ(g.frame(f)[b].rotation, s.frames[f][b].rotation) << f;
        }
    }
}

TEST(SmdParse, TimeIsBoundedAndKeysAreCapped) {
    auto lines = with(kBase, 7, "time 2147483647");
    EXPECT_EQ(parse_ref(join_lines(lines)).bones.size(), 2u);
    expect_error([&] { parse_ref(join_lines(with(kBase, 7, "time 2147483648"))); }, kName, 7,
                 "time 2147483648 out of range (0..2147483647)");
    expect_error([&] { parse_ref(join_lines(with(kBase, 7, "time 99999999999999999999"))); }, kName, 7,
                 "out of range");

    // 4096 reference bones: at most 2^24 / 4096 = 4096 key frames. The 4097th
    // `time` line fails, after any earlier error, without storing a key.
    std::ostringstream ref_text, anim_text;
    ref_text << "nodes\n";
    for (int b = 0; b < 4096; ++b) ref_text << b << " \"b" << b << "\" -1\n";
    ref_text << "end\nskeleton\ntime 0\nend\n";
    const SmdModel big = parse_ref(ref_text.str());
    ASSERT_EQ(big.bones.size(), 4096u);
    anim_text << "nodes\n0 \"b7\" -1\nend\nskeleton\n";
    for (int t = 0; t < 4096; ++t) anim_text << "time " << t << "\n";
    const std::string anim = anim_text.str();
    const SmdSkeletonAnim ok =
        raykit::parse_smd_animation(anim.substr(0, anim.find("time 100\n")) + "end\n", kName, big.bones);
    EXPECT_EQ(ok.key_count(), 100u);
    EXPECT_EQ(ok.frames.back().size(), 4096u);
    const std::string over = anim + "0 1 2 3 4 5 6\ntime 4096\nend\n";
    expect_error([&] { raykit::parse_smd_animation(over, kName, big.bones); }, kName, 4102,
                 "animation too large: more than 16777216 bone poses (4097 key frames x 4096 reference bones)");
    // An earlier error still comes first.
    const std::string earlier = anim + "0 1 2 3 4 5 x\ntime 4096\nend\n";
    expect_error([&] { raykit::parse_smd_animation(earlier, kName, big.bones); }, kName, 4101, "malformed number 'x'");
}

TEST(SmdParse, ManyBonesTimesAndLinksStayLinear) {
    // A reference with 20,000 bones and 20,000 `time` lines: it keeps one frame
    // (the old loader copied every frame: 9.6 GB).
    std::ostringstream out;
    out << "nodes\n";
    const int nb = 20000;
    for (int b = 0; b < nb; ++b) out << b << " \"b" << b << "\" " << b - 1 << "\n";
    out << "end\nskeleton\n";
    for (int t = 0; t < 20000; ++t) out << "time " << t << "\n" << t % nb << " 1 0 0 0 0 0\n";
    out << "end\ntriangles\nmat\n";
    // One vertex line with 3 links per bone (60,000 links): weights add per bone.
    out << "0 0 0 0 0 0 1 0 0 " << 3 * nb;
    for (int k = 0; k < 3 * nb; ++k) out << " " << k % nb << " 1";
    out << "\n0 1 0 0 0 0 1 0 0\n0 0 1 0 0 0 1 0 0\nend\n";
    const std::string text = out.str();
    const SmdModel m = parse_ref(text);
    ASSERT_EQ(m.bones.size(), static_cast<std::size_t>(nb));
    EXPECT_EQ(m.bind_pose[0].position.x, 1.0f);
    EXPECT_EQ(m.bind_pose[1].position.x, 0.0f);  // listed only in later frames
    ASSERT_EQ(m.weights[0].links.size(), static_cast<std::size_t>(nb));
    double sum = 0.0;
    for (std::size_t k = 0; k < m.weights[0].links.size(); ++k) {
        EXPECT_EQ(m.weights[0].links[k].bone, k);
        sum += m.weights[0].links[k].weight;
    }
    EXPECT_NEAR(sum, 1.0, 1e-4);
    EXPECT_NEAR(m.weights[0].links[123].weight, 1.0 / nb, 1e-9);
    // Duplicate links whose float sum would overflow stay finite.
    const SmdModel h = parse_ref(join_lines(with(kBase, 15, "0 0 1 0 0 0 1 0 1 3 0 3e38 0 3e38 1 3e38")));
    ASSERT_EQ(h.weights[2].links.size(), 2u);
    EXPECT_NEAR(h.weights[2].links[0].weight, 2.0f / 3.0f, 1e-6f);
    EXPECT_NEAR(h.weights[2].links[1].weight, 1.0f / 3.0f, 1e-6f);
}

TEST(SmdParse, AnimationSkipsTriangles) {
    const SmdModel ref = parse_ref(join_lines(kBase));
    // A broken vertex line inside `triangles` does not matter to an animation.
    const SmdSkeletonAnim a =
        raykit::parse_smd_animation(join_lines(with(kBase, 13, "garbage")), kName, ref.bones, ref.bind_pose);
    EXPECT_EQ(a.frames.size(), 1u);
    expect_error([&] { raykit::parse_smd_animation(join_lines(first_lines(kBase, 14)), kName, ref.bones); }, kName,
                 11, "'triangles' block has no 'end'");
}

TEST(SmdParse, NumberForms) {
    const SmdModel m = parse_ref(join_lines(with(kBase, 13, "+0 .5 -.5 5. 1e-05 1E+2 -0 0.25 +0.75")));
    EXPECT_EQ(m.mesh.positions[0], vec3(0.5f, -0.5f, 5.0f));
    EXPECT_EQ(m.mesh.normals[0], vec3(1e-05f, 100.0f, -0.0f));
    EXPECT_EQ(m.mesh.texcoords[0], raykit::vec2(0.25f, 0.75f));
}

TEST(SmdTextures, EachFolderIsListedOncePerLoad) {
    // 600 files, 1,800 materials: each file named by its exact name, in another
    // case, and without its extension; plus a subfolder and a missing texture.
    TempDir dir;
    const int n = 600;
    char name[64];
    for (int i = 0; i < n; ++i) {
        std::snprintf(name, sizeof name, "tex_%03d.%s", i, i % 2 ? "bmp" : "PNG");
        dir.write(name, "x");
    }
    fs::create_directories(dir.path() / "Sub");
    dir.write("Sub/stone.jpg", "x");
    dir.write("Sub/stone.txt", "x");
    std::string text = join_lines(first_lines(kBase, 11));
    std::vector<std::pair<std::string, std::string>> expect;  // material -> map_kd file name
    auto add = [&](const std::string& mat, const std::string& file) {
        text += mat + "\n0 0 0 0 0 0 1 0 0\n1 1 0 0 0 0 1 1 0\n0 0 1 0 0 0 1 0 1\n";
        expect.emplace_back(mat, file);
    };
    for (int i = 0; i < n; ++i) {
        std::snprintf(name, sizeof name, "tex_%03d.%s", i, i % 2 ? "bmp" : "PNG");
        add(name, name);  // exact
        std::string upper = name;
        for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
        add(upper, name);  // case-insensitive
        std::snprintf(name, sizeof name, "Tex_%03d", i);
        char file[64];
        std::snprintf(file, sizeof file, "tex_%03d.%s", i, i % 2 ? "bmp" : "PNG");
        add(name, file);  // extension added
    }
    add("Sub/STONE", "Sub/stone.jpg");
    add("absent", "absent");
    text += "end\n";
    const SmdModel m = parse_ref(text, dir.path());
    ASSERT_EQ(m.mesh.materials.size(), expect.size());
    for (std::size_t i = 0; i < expect.size(); ++i) {
        EXPECT_EQ(fs::path(m.mesh.materials[i].map_kd), dir.path() / expect[i].second) << expect[i].first;
    }
    ASSERT_EQ(m.mesh.warnings.size(), 1u);
    EXPECT_NE(m.mesh.warnings[0].find("texture 'absent' not found"), std::string::npos) << m.mesh.warnings[0];

    raykit::SmdTextureFinder finder(dir.path());
    for (const auto& [mat, file] : expect) (void)finder.find(mat);
    EXPECT_EQ(finder.listings(), 2u);  // the folder and Sub, once each
    EXPECT_EQ(finder.find("./tex_001").first, dir.path() / "." / "tex_001.bmp");
    EXPECT_EQ(finder.listings(), 2u);  // "./" is the same folder
    EXPECT_EQ(raykit::smd_resolve_texture(dir.path(), "TEX_002").first, dir.path() / "tex_002.PNG");
}

// ------------------------------------------------------------------ malformed input

struct BadCase {
    const char* what;
    std::vector<std::string> lines;
    std::size_t line;
    const char* fragment;
};

TEST(SmdMalformed, EveryCaseNamesFileAndLine) {
    const std::vector<BadCase> cases = {
        // truncated blocks and missing `end`
        {"triangle cut short by end", without(kBase, 15), 15, "has 2 of 3 vertex lines before 'end'"},
        {"triangle cut short by eof", first_lines(kBase, 14), 12, "end of file inside the triangle"},
        {"triangle cut short by a material", with(kBase, 15, "tex.bmp"), 15, "expected a vertex line"},
        {"nodes without end", first_lines(kBase, 4), 2, "'nodes' block has no 'end'"},
        {"nodes end missing before skeleton", without(kBase, 5), 5, "malformed bone id 'skeleton'"},
        {"skeleton without end", first_lines(kBase, 9), 6, "'skeleton' block has no 'end'"},
        {"triangles without end", first_lines(kBase, 15), 11, "'triangles' block has no 'end'"},
        {"vertexanimation without end", {"nodes", "end", "skeleton", "time 0", "end", "vertexanimation", "time 0"},
         6, "'vertexanimation' block has no 'end'"},
        {"no skeleton block", first_lines(kBase, 5), 5, "no 'skeleton' block"},
        {"no nodes block", {"version 1"}, 1, "no 'nodes' block"},
        {"empty file", {}, 1, "no 'nodes' block"},
        {"only comments", {"// nothing", "", "# here"}, 3, "no 'nodes' block"},
        {"skeleton before nodes", {"version 1", "skeleton", "time 0", "end"}, 2, "before the 'nodes' block"},
        {"triangles before nodes", {"triangles", "end"}, 1, "before the 'nodes' block"},
        {"skeleton without time", with(without(without(kBase, 9), 8), 7, "end"), 7,
         "has no 'time' frame"},
        {"second nodes block", inserted(kBase, 6, "nodes"), 6, "second 'nodes' block"},
        {"text after a block keyword", with(kBase, 11, "triangles now"), 11, "unexpected text after 'triangles'"},
        // bone indices out of range
        {"skeleton bone out of range", with(kBase, 9, "2 1 0 0 0 0 0"), 9, "bone index 2 out of range (2 bones)"},
        {"skeleton bone negative", with(kBase, 9, "-1 1 0 0 0 0 0"), 9, "bone index -1 out of range"},
        {"vertex parent out of range", with(kBase, 13, "5 0 0 0 0 0 1 0 0"), 13, "parent bone 5 is not a bone"},
        {"vertex parent negative", with(kBase, 13, "-1 0 0 0 0 0 1 0 0"), 13, "parent bone -1 is not a bone"},
        {"bone id out of range", with(kBase, 4, "70000 \"child\" 0"), 4, "bone id 70000 out of range"},
        // links
        {"link to an unknown bone", with(kBase, 15, "0 0 1 0 0 0 1 0 1 2 0 0.5 7 0.5"), 15,
         "link to bone 7 is not a bone"},
        {"link count larger than the links", with(kBase, 15, "0 0 1 0 0 0 1 0 1 3 0 0.5 1 0.5"), 15,
         "declares 3 links"},
        {"link count smaller than the links", with(kBase, 15, "0 0 1 0 0 0 1 0 1 1 0 0.5 1 0.5"), 15,
         "declares 1 links"},
        {"negative link count", with(kBase, 15, "0 0 1 0 0 0 1 0 1 -1"), 15, "negative link count"},
        {"negative weight", with(kBase, 15, "0 0 1 0 0 0 1 0 1 2 0 -0.5 1 0.5"), 15, "negative link weight"},
        // NaN, inf, overflow, non-numeric fields
        {"nan position", with(kBase, 14, "1 nan 0 0 0 0 1 1 0"), 14, "non-finite number 'nan'"},
        {"NaN normal", with(kBase, 14, "1 1 0 0 0 NaN 1 1 0"), 14, "non-finite number 'NaN'"},
        {"inf uv", with(kBase, 14, "1 1 0 0 0 0 1 inf 0"), 14, "non-finite number 'inf'"},
        {"-inf in skeleton", with(kBase, 8, "0 0 0 0 -inf 0 0"), 8, "non-finite number '-inf'"},
        {"nan weight", with(kBase, 15, "0 0 1 0 0 0 1 0 1 2 0 nan 1 0.5"), 15, "non-finite number 'nan'"},
        {"float overflow", with(kBase, 13, "0 1e39 0 0 0 0 1 0 0"), 13, "overflows a float"},
        {"non-numeric position", with(kBase, 13, "0 abc 0 0 0 0 1 0 0"), 13, "malformed number 'abc'"},
        {"number with junk", with(kBase, 8, "0 0 0 0 1.5x 0 0"), 8, "malformed number '1.5x'"},
        {"non-numeric vertex parent", with(kBase, 13, "a 0 0 0 0 0 1 0 0"), 13, "expected a vertex line"},
        {"fractional vertex parent", with(kBase, 13, "0.5 0 0 0 0 0 1 0 0"), 13, "expected a vertex line"},
        {"non-numeric bone id", with(kBase, 4, "x \"child\" 0"), 4, "malformed bone id 'x'"},
        {"non-numeric parent id", with(kBase, 4, "1 \"child\" p"), 4, "malformed parent id 'p'"},
        {"non-numeric skeleton bone", with(kBase, 9, "one 1 0 0 0 0 0"), 9, "malformed bone index 'one'"},
        {"non-integer time", with(kBase, 7, "time 0.5"), 7, "malformed time '0.5'"},
        {"non-integer link count", with(kBase, 15, "0 0 1 0 0 0 1 0 1 x 0 0.5 1 0.5"), 15,
         "malformed link count 'x'"},
        {"non-numeric link bone", with(kBase, 15, "0 0 1 0 0 0 1 0 1 2 b 0.5 1 0.5"), 15,
         "malformed link to bone 'b'"},
        {"non-numeric version", with(kBase, 1, "version one"), 1, "malformed version 'one'"},
        // the bone hierarchy
        {"parent cycle", with(kBase, 3, "0 \"root\" 1"), 3, "parent cycle through bone 0 'root'"},
        {"self parent", with(kBase, 4, "1 \"child\" 1"), 4, "parent cycle through bone 1 'child'"},
        {"parent not a bone", with(kBase, 4, "1 \"child\" 5"), 4, "parent 5 of bone 1 'child' is not a bone"},
        {"parent below -1", with(kBase, 4, "1 \"child\" -2"), 4, "parent -2 of bone 1 'child' is not a bone"},
        {"duplicate bone id", with(kBase, 4, "0 \"child\" 0"), 4, "duplicate bone id 0 (first at line 3)"},
        {"missing bone id", with(kBase, 4, "2 \"child\" 0"), 5, "id 1 is missing"},
        {"largest bone id alone", with(kBase, 4, "65534 \"child\" 0"), 5, "id 1 is missing"},
        {"duplicate bone name", with(kBase, 4, "1 \"root\" 0"), 4, "duplicate bone name 'root'"},
        {"unterminated quote", with(kBase, 4, "1 \"child 0"), 4, "without a closing quote"},
        {"node line without parent", with(kBase, 4, "1 \"child\""), 4, "bone line needs"},
        // skeleton structure
        {"pose before time", without(kBase, 7), 7, "before the first 'time' line"},
        {"bone twice in a frame", with(kBase, 9, "0 1 0 0 0 0 0"), 9, "bone 0 listed twice in time 0"},
        {"time not increasing", inserted(kBase, 10, "time 0"), 10, "time 0 does not follow time 0"},
        {"negative time", with(kBase, 7, "time -1"), 7, "negative time"},
        {"time past the limit", inserted(kBase, 10, "time 2147483648"), 10, "out of range (0..2147483647)"},
        {"too few pose fields", with(kBase, 8, "0 0 0 0 0 0"), 8, "needs 7 fields"},
        {"too many pose fields", with(kBase, 8, "0 0 0 0 0 0 0 0"), 8, "needs 7 fields"},
        // vertex lines
        {"too few vertex fields", with(kBase, 13, "0 0 0 0 0 0 1 0"), 13, "at least 9 fields"},
        // top level
        {"unknown statement", inserted(kBase, 11, "bogus"), 11, "unknown statement 'bogus'"},
        {"stray end", inserted(kBase, 11, "end"), 11, "unknown statement 'end'"},
        {"version 2", with(kBase, 1, "version 2"), 1, "unsupported SMD version '2'"},
        {"version after a block", inserted(kBase, 6, "version 1"), 6, "'version' after the first block"},
    };
    for (const BadCase& c : cases) {
        SCOPED_TRACE(c.what);
        expect_error([&] { parse_ref(join_lines(c.lines)); }, kName, c.line, c.fragment);
    }
}

TEST(SmdMalformed, AnimationFilesAreCheckedToo) {
    const SmdModel ref = parse_ref(join_lines(kBase));
    const std::vector<BadCase> cases = {
        {"bone out of range", with(kBase, 9, "5 1 0 0 0 0 0"), 9, "bone index 5 out of range"},
        {"nan pose", with(kBase, 9, "1 nan 0 0 0 0 0"), 9, "non-finite"},
        {"cycle", with(kBase, 3, "0 \"root\" 0"), 3, "parent cycle"},
        {"skeleton without end", first_lines(kBase, 9), 6, "'skeleton' block has no 'end'"},
        {"no skeleton", first_lines(kBase, 5), 5, "no 'skeleton' block"},
    };
    for (const BadCase& c : cases) {
        SCOPED_TRACE(c.what);
        expect_error([&] { raykit::parse_smd_animation(join_lines(c.lines), kName, ref.bones, ref.bind_pose); },
                     kName, c.line, c.fragment);
    }
}

TEST(SmdMalformed, FilesAreNamedInErrors) {
    TempDir dir;
    const fs::path bad = dir.write("BAD.SMD", join_lines(with(kBase, 14, "1 1 0 0 0 0 1 1 nan")));
    expect_error([&] { raykit::load_smd_reference(bad); }, bad.string(), 14, "non-finite");
    const fs::path anim = dir.write("anim.smd", join_lines(first_lines(kBase, 9)));
    const SmdModel ref = parse_ref(join_lines(kBase));
    expect_error([&] { raykit::load_smd_animation(anim, ref); }, anim.string(), 6, "no 'end'");
    expect_error([&] { raykit::load_smd_reference(dir.path() / "absent.smd"); }, (dir.path() / "absent.smd").string(),
                 0, "cannot open");
}

// ------------------------------------------------------------------ real files

struct CorpusFile {
    fs::path path;
    bool has_triangles = false;
};

bool is_smd(const fs::path& p) {
    std::string ext = p.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    return ext == ".smd";
}

std::vector<CorpusFile> corpus() {
    std::vector<CorpusFile> out;
    for (const fs::path& root : {shared_smd_dir(), kAssimpSmdDir}) {
        std::error_code ec;
        if (!fs::is_directory(root, ec)) continue;
        for (const auto& e : fs::recursive_directory_iterator(root, ec)) {
            if (!e.is_regular_file() || !is_smd(e.path())) continue;
            const OracleMesh o = oracle_read(e.path());
            out.push_back({e.path(), !o.corners.empty()});
        }
    }
    std::sort(out.begin(), out.end(), [](const CorpusFile& a, const CorpusFile& b) { return a.path < b.path; });
    return out;
}

// Files that may not load, with the reason. Empty: every file of the corpus loads.
const std::map<std::string, std::string> kKnownFailures = {};

TEST(SmdCorpus, EveryFileLoadsOrIsListed) {
    const std::vector<CorpusFile> files = corpus();
    if (files.empty()) GTEST_SKIP() << "no SMD corpus (" << shared_smd_dir() << ", " << kAssimpSmdDir << ")";
    std::size_t refs = 0, anims = 0;
    for (const CorpusFile& f : files) {
        SCOPED_TRACE(f.path.string());
        const auto known = kKnownFailures.find(f.path.filename().string());
        try {
            const SmdModel m = raykit::load_smd_reference(f.path);
            EXPECT_FALSE(m.bones.empty());
            EXPECT_EQ(m.bind_pose.size(), m.bones.size());
            if (f.has_triangles) {
                ++refs;
                check_against_oracle(f.path);
            } else {
                // An animation: load it against every reference of its folder.
                for (const CorpusFile& r : files) {
                    if (!r.has_triangles || r.path.parent_path() != f.path.parent_path()) continue;
                    const SmdModel ref = raykit::load_smd_reference(r.path);
                    const SmdSkeletonAnim a = raykit::load_smd_animation(f.path, ref);
                    EXPECT_FALSE(a.frames.empty());
                    EXPECT_TRUE(a.warnings.empty()) << a.warnings.front();
                    ++anims;
                }
            }
        } catch (const std::exception& e) {
            EXPECT_NE(known, kKnownFailures.end()) << "failed to load: " << e.what();
        }
    }
    std::printf("[ info     ] %zu SMD files: %zu references checked against the oracle, %zu animation loads\n",
                files.size(), refs, anims);
}

TEST(SmdCorpus, HalfLife1DwarfAndHalfLife2Goblin) {
    const fs::path dwarf = shared_smd_dir() / "hl1_dwarf" / "ref.SMD";
    const fs::path goblin = shared_smd_dir() / "hl2_goblin" / "Goblin_Reference.smd";
    if (!fs::exists(dwarf) || !fs::exists(goblin)) GTEST_SKIP() << "shared SMD data not found";
    const SmdModel d = raykit::load_smd_reference(dwarf);
    EXPECT_EQ(d.bones.size(), 47u);
    EXPECT_EQ(d.mesh.triangles.size(), 1896u);
    int roots = 0;
    for (const auto& b : d.bones) roots += b.parent < 0;
    EXPECT_EQ(roots, 3);
    EXPECT_TRUE(d.mesh.warnings.empty());
    ASSERT_EQ(d.mesh.materials.size(), 2u);
    EXPECT_TRUE(fs::exists(d.mesh.materials[0].map_kd));
    const SmdSkeletonAnim run = raykit::load_smd_animation(dwarf.parent_path() / "run.SMD", d);
    EXPECT_EQ(run.frames.size(), 13u);

    const SmdModel g = raykit::load_smd_reference(goblin);
    EXPECT_EQ(g.bones.size(), 35u);
    EXPECT_EQ(g.mesh.triangles.size(), 2363u);
    // Half-Life 2 lines name bone 0 as parent; the real bone is in the link.
    std::size_t not_root = 0;
    for (const auto& w : g.weights) {
        ASSERT_EQ(w.links.size(), 1u);
        EXPECT_EQ(w.links[0].weight, 1.0f);
        not_root += w.links[0].bone != 0;
    }
    EXPECT_GT(not_root, g.weights.size() / 2);
    const SmdSkeletonAnim anim = raykit::load_smd_animation(goblin.parent_path() / "Goblin_Anim.smd", g);
    EXPECT_EQ(anim.frames.size(), 800u);
}

}  // namespace
