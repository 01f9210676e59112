// Tests for raykit/io/obj.hpp: hand-written fixtures for every rule of the
// loader, and a comparison against tinyobjloader on every real OBJ file found
// under <repo>/../shared/data/obj and /usr/share/assimp/models/OBJ.
#include "raykit/io/obj.hpp"

#include <gtest/gtest.h>
#include <tiny_obj_loader.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cfloat>
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

#include <sys/stat.h>

#include "test_text.hpp"

namespace fs = std::filesystem;
using raykit::kNoMaterial;
using raykit::Mesh;
using raykit::ParseError;
using raykit::vec2;
using raykit::vec3;

namespace {

// ------------------------------------------------------------------ helpers

constexpr const char* kFixtureName = "fixture.obj";

Mesh parse(std::string_view text, const fs::path& base_dir = {}, const raykit::ObjOptions& options = {}) {
    return raykit::parse_obj(text, kFixtureName, base_dir, options);
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

/// Expects `f` to throw a ParseError for `file` at `line` whose message
/// contains `fragment`, and checks the "FILE:LINE: " prefix of what().
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

void expect_obj_error(std::string_view text, std::size_t line, const std::string& fragment) {
    SCOPED_TRACE(std::string(text));
    expect_error([&] { parse(text); }, kFixtureName, line, fragment);
}

/// A scratch folder, removed with its contents at the end of the test.
class TempDir {
public:
    TempDir() {
        std::random_device rd;
        path_ = fs::temp_directory_path() / ("raykit_test_obj_" + std::to_string(rd()) + std::to_string(rd()));
        fs::create_directories(path_);
    }
    ~TempDir() {
        std::error_code ec;
        fs::remove_all(path_, ec);
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;

    const fs::path& path() const { return path_; }
    fs::path write(const std::string& relative, std::string_view content) const {
        const fs::path p = path_ / relative;
        fs::create_directories(p.parent_path());
        std::ofstream out(p, std::ios::binary);
        out.write(content.data(), static_cast<std::streamsize>(content.size()));
        return p;
    }

private:
    fs::path path_;
};

std::vector<std::array<std::uint32_t, 3>> triangles_of(const Mesh& m) {
    std::vector<std::array<std::uint32_t, 3>> out;
    for (const raykit::Triangle& t : m.triangles) out.push_back({t.v[0], t.v[1], t.v[2]});
    return out;
}

using Tri = std::array<std::uint32_t, 3>;

/// Checks the structural invariants every loaded Mesh must satisfy.
void expect_valid_mesh(const Mesh& m) {
    EXPECT_EQ(m.material_ids.size(), m.triangles.size());
    EXPECT_TRUE(m.normals.empty() || m.normals.size() == m.positions.size());
    EXPECT_TRUE(m.texcoords.empty() || m.texcoords.size() == m.positions.size());
    for (const raykit::Triangle& t : m.triangles) {
        for (std::uint32_t i : t.v) ASSERT_LT(i, m.positions.size());
    }
    for (std::uint32_t id : m.material_ids) {
        if (id != kNoMaterial) {
            ASSERT_LT(id, m.materials.size());
        }
    }
    for (const auto* list : {&m.objects, &m.groups}) {
        std::uint32_t next = 0;
        for (const raykit::Group& g : *list) {
            EXPECT_GE(g.first_triangle, next);
            EXPECT_LE(std::uint64_t{g.first_triangle} + g.triangle_count, m.triangles.size());
            next = g.first_triangle + g.triangle_count;
        }
    }
    for (const vec3& p : m.positions) EXPECT_TRUE(raykit::is_finite(p));
}

std::string material_name(const Mesh& m, std::size_t tri) {
    const std::uint32_t id = m.material_ids[tri];
    return id == kNoMaterial ? std::string() : m.materials[id].name;
}

// ------------------------------------------------------------------ geometry and faces

TEST(ObjParse, SingleTriangle) {
    const Mesh m = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    expect_valid_mesh(m);
    ASSERT_EQ(m.positions.size(), 3u);
    EXPECT_EQ(m.positions[1], vec3(1, 0, 0));
    EXPECT_EQ(triangles_of(m), (std::vector<Tri>{{0, 1, 2}}));
    EXPECT_TRUE(m.normals.empty());
    EXPECT_TRUE(m.texcoords.empty());
    EXPECT_EQ(m.material_ids, std::vector<std::uint32_t>{kNoMaterial});
    EXPECT_TRUE(m.objects.empty());
    EXPECT_TRUE(m.groups.empty());
    EXPECT_TRUE(m.warnings.empty());
}

TEST(ObjParse, EmptyAndCommentOnlyInputs) {
    for (std::string_view text : {"", "\n", "# only a comment", "  \n\t\n# x\n", "\r\n"}) {
        const Mesh m = parse(text);
        EXPECT_TRUE(m.positions.empty());
        EXPECT_TRUE(m.triangles.empty());
    }
}

TEST(ObjParse, QuadIsFannedFromFirstCornerWhateverItsShape) {
    // The 1-3 diagonal is much shorter than 0-2: the fan still uses 0-2.
    const Mesh m = parse("v 0 0 0\nv 10 -1 0\nv 20 0 0\nv 10 1 0\nf 1 2 3 4\n");
    EXPECT_EQ(triangles_of(m), (std::vector<Tri>{{0, 1, 2}, {0, 2, 3}}));
}

TEST(ObjParse, PentagonAndHexagonFanOrder) {
    const Mesh m = parse(
        "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 2 0\nv -1 1 0\n"
        "f 1 2 3 4 5\n"
        "f 6 5 4 3 2 1\n");
    EXPECT_EQ(triangles_of(m), (std::vector<Tri>{{0, 1, 2},
                                                  {0, 2, 3},
                                                  {0, 3, 4},
                                                  {5, 4, 3},
                                                  {5, 3, 2},
                                                  {5, 2, 1},
                                                  {5, 1, 0}}));
}

TEST(ObjParse, ConcavePolygonIsStillFanned) {
    // An arrow-head: fan triangles (0,1,2), (0,2,3) even though one lies outside.
    const Mesh m = parse("v 0 0 0\nv 2 1 0\nv 0 0.2 0\nv -2 1 0\nf 1 2 3 4\n");
    EXPECT_EQ(triangles_of(m), (std::vector<Tri>{{0, 1, 2}, {0, 2, 3}}));
}

TEST(ObjParse, AllFourCornerForms) {
    const Mesh m = parse(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
        "vt 0.25 0.5\nvt 0.75 1\n"
        "vn 0 0 1\nvn 0 1 0\n"
        "f 1 2/1 3//2 4/2/1\n");
    expect_valid_mesh(m);
    ASSERT_EQ(m.positions.size(), 4u);
    ASSERT_EQ(m.normals.size(), 4u);
    ASSERT_EQ(m.texcoords.size(), 4u);
    EXPECT_EQ(triangles_of(m), (std::vector<Tri>{{0, 1, 2}, {0, 2, 3}}));
    EXPECT_EQ(m.positions[3], vec3(1, 1, 0));
    // Zero where a corner has none.
    EXPECT_EQ(m.normals[0], vec3(0));
    EXPECT_EQ(m.normals[1], vec3(0));
    EXPECT_EQ(m.normals[2], vec3(0, 1, 0));
    EXPECT_EQ(m.normals[3], vec3(0, 0, 1));
    EXPECT_EQ(m.texcoords[0], vec2(0));
    EXPECT_EQ(m.texcoords[1], vec2(0.25f, 0.5f));
    EXPECT_EQ(m.texcoords[2], vec2(0));
    EXPECT_EQ(m.texcoords[3], vec2(0.75f, 1.0f));
}

TEST(ObjParse, NormalsOnlyOrTexcoordsOnly) {
    const Mesh n = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n");
    EXPECT_EQ(n.normals.size(), 3u);
    EXPECT_TRUE(n.texcoords.empty());
    const Mesh t = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.5\nf 1/1 2/1 3/1\n");
    EXPECT_TRUE(t.normals.empty());
    ASSERT_EQ(t.texcoords.size(), 3u);
    EXPECT_EQ(t.texcoords[0], vec2(0.5f, 0.0f));  // vt v defaults to 0
    // vt / vn lines that no face uses do not create arrays.
    const Mesh u = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1 2 3\n");
    EXPECT_TRUE(u.normals.empty());
    EXPECT_TRUE(u.texcoords.empty());
}

TEST(ObjParse, NegativeIndicesAreRelativeToWhatIsDefinedSoFar) {
    const Mesh m = parse(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
        "vt 0 0\nvt 1 0\nvt 0 1\n"
        "vn 1 0 0\nvn 0 1 0\n"
        "f -3/-3/-2 -2/-2/-1 -1/-1/-1\n"
        "v 5 5 5\nvt 0.5 0.5\nvn 0 0 1\n"
        "f -4/-4/-3 -1/-1/-1 -2/-2/-2\n");
    expect_valid_mesh(m);
    ASSERT_EQ(m.triangles.size(), 2u);
    auto corner = [&](int t, int c) { return m.triangles[t].v[c]; };
    EXPECT_EQ(m.positions[corner(0, 0)], vec3(0, 0, 0));
    EXPECT_EQ(m.positions[corner(0, 2)], vec3(0, 1, 0));
    EXPECT_EQ(m.normals[corner(0, 0)], vec3(1, 0, 0));
    EXPECT_EQ(m.normals[corner(0, 1)], vec3(0, 1, 0));
    EXPECT_EQ(m.texcoords[corner(0, 1)], vec2(1, 0));
    EXPECT_EQ(m.positions[corner(1, 1)], vec3(5, 5, 5));
    EXPECT_EQ(m.texcoords[corner(1, 1)], vec2(0.5f, 0.5f));
    EXPECT_EQ(m.normals[corner(1, 1)], vec3(0, 0, 1));
    EXPECT_EQ(m.positions[corner(1, 2)], vec3(0, 1, 0));
    EXPECT_EQ(m.normals[corner(1, 0)], vec3(1, 0, 0));
    // Same index triple in both faces (-4/-4/-3 then -3/-3/-2) -> same vertex.
    EXPECT_EQ(corner(1, 0), corner(0, 0));
}

TEST(ObjParse, VertexDeduplicationByIndexTriple) {
    const Mesh m = parse(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
        "vt 0 0\nvt 1 1\n"
        "f 1/1 2/1 3/1\n"
        "f 2/1 4/1 3/1\n"    // 2/1 and 3/1 shared
        "f 1/2 2/1 3/1\n");  // 1/2 is a new vertex with the same position as 1/1
    expect_valid_mesh(m);
    EXPECT_EQ(m.positions.size(), 5u);
    EXPECT_EQ(triangles_of(m), (std::vector<Tri>{{0, 1, 2}, {1, 3, 2}, {4, 1, 2}}));
    EXPECT_EQ(m.positions[4], m.positions[0]);
    EXPECT_EQ(m.texcoords[4], vec2(1, 1));
}

TEST(ObjParse, PositionOnlyFilesKeepTheVListOrder) {
    const Mesh m = parse(
        "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nv 4 0 0\n"
        "f 5 3 2\n"
        "f 2 3 4\n");  // v 1 is never used
    expect_valid_mesh(m);
    ASSERT_EQ(m.positions.size(), 4u);
    for (int i = 0; i < 4; ++i) EXPECT_EQ(m.positions[i], vec3(float(i + 1), 0, 0));
    EXPECT_EQ(triangles_of(m), (std::vector<Tri>{{3, 1, 0}, {0, 1, 2}}));

    // All used: positions are exactly the v list.
    const Mesh all = parse("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 3 1 2\n");
    ASSERT_EQ(all.positions.size(), 3u);
    EXPECT_EQ(all.positions[2], vec3(2, 0, 0));
    EXPECT_EQ(triangles_of(all), (std::vector<Tri>{{2, 0, 1}}));
}

TEST(ObjParse, ExtraVertexComponentsAreIgnored) {
    const Mesh m = parse(
        "v 1 2 3 0.5\n"          // w
        "v 4 5 6 0.1 0.2 0.3\n"  // vertex colour
        "v 7 8 9 1\n"
        "vt 0.1 0.2 0.3\n"  // 3-component texture coordinate
        "f 1/1 2/1 3/1\n");
    EXPECT_EQ(m.positions[0], vec3(1, 2, 3));
    EXPECT_EQ(m.positions[1], vec3(4, 5, 6));
    EXPECT_EQ(m.texcoords[0], vec2(0.1f, 0.2f));
}

TEST(ObjParse, NumberForms) {
    const Mesh m = parse(
        "v .5 -.5 +1\n"
        "v 5. 1e-05 1E+5\n"
        "v +.25 -5. 00012\n"
        "v 1e-50 -1e-50 3.4028234e38\n"
        "v 1e-40 1.5E-3 -0\n"
        "f 1 2 3\nf 3 4 5\n");
    ASSERT_EQ(m.positions.size(), 5u);
    EXPECT_EQ(m.positions[0], vec3(0.5f, -0.5f, 1.0f));
    EXPECT_EQ(m.positions[1], vec3(5.0f, 1e-05f, 1e5f));
    EXPECT_EQ(m.positions[2], vec3(0.25f, -5.0f, 12.0f));
    EXPECT_EQ(m.positions[3].x, 0.0f);  // underflow -> 0
    EXPECT_EQ(m.positions[3].y, 0.0f);
    EXPECT_TRUE(std::signbit(m.positions[3].y));
    EXPECT_EQ(m.positions[3].z, 3.4028234e38f);
    EXPECT_EQ(m.positions[4].x, 1e-40f);  // subnormal kept
    EXPECT_EQ(m.positions[4].y, 1.5e-3f);
}

// ------------------------------------------------------------------ lexical rules

TEST(ObjLexical, LineContinuations) {
    const Mesh m = parse(
        "v 1 \\\n2 \\\n  3\n"  // continued twice
        "v 4 5\\\n"            // backslash right after a number
        "\n"                   // blank lines inside a continuation are skipped
        "   \n"
        "6\n"
        "v 7 8 9\n"
        "f 1 \\\n 2 3\n");
    ASSERT_EQ(m.positions.size(), 3u);
    EXPECT_EQ(m.positions[0], vec3(1, 2, 3));
    EXPECT_EQ(m.positions[1], vec3(4, 5, 6));
    EXPECT_EQ(m.positions[2], vec3(7, 8, 9));
    ASSERT_EQ(m.triangles.size(), 1u);
}

TEST(ObjLexical, ContinuationInsideCommentSwallowsTheNextLine) {
    const Mesh m = parse(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
        "# a comment \\\n"
        "f 1 2 3\n"  // part of the comment
        "f 3 2 1\n");
    EXPECT_EQ(triangles_of(m), (std::vector<Tri>{{2, 1, 0}}));
}

TEST(ObjLexical, ContinuationWithTrailingBlanksAndAtEndOfFile) {
    const Mesh m = parse("v 1 2 \\  \t\r\n3\r\nv 0 0 0\nv 1 1 1\nf 1 2 3 \\");
    ASSERT_EQ(m.positions.size(), 3u);
    EXPECT_EQ(m.positions[0], vec3(1, 2, 3));
    EXPECT_EQ(m.triangles.size(), 1u);
}

TEST(ObjLexical, LineNumbersCountPhysicalLinesAcrossContinuations) {
    // The bad logical line starts on physical line 3.
    expect_obj_error("v 0 0 \\\n0\nv 1 2 \\\n x\n", 3, "malformed number 'x'");
    expect_obj_error("v 0 0 \\\n0\nv 1 1 1\nv 2 2 \\\n\n\n2\nv 1 2\n", 8, "needs at least 3");
}

TEST(ObjLexical, CrlfLineEndings) {
    const Mesh m = parse("v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nvn 0 0 1\r\ng my group\r\nusemtl a b\r\nf 1//1 2//1 3//1\r\n");
    ASSERT_EQ(m.triangles.size(), 1u);
    EXPECT_EQ(m.normals[0], vec3(0, 0, 1));
    ASSERT_EQ(m.groups.size(), 1u);
    EXPECT_EQ(m.groups[0].name, "my group");
    ASSERT_EQ(m.warnings.size(), 1u);
    EXPECT_NE(m.warnings[0].find("'a b'"), std::string::npos) << m.warnings[0];
    expect_obj_error("v 0 0 0\r\nv 1 0 0\r\nv 0 1 x\r\n", 3, "malformed number 'x'");
    // Old Mac CR-only files are not supported: they read as one line.
}

TEST(ObjLexical, WhitespaceCommentsAndMissingFinalNewline) {
    const Mesh m = parse(
        "   # indented comment\n"
        "\tv\t0  0\t\t0   \n"
        "v 1 0 0# comment right after a number\n"
        "  v   0    1     0\n"
        "\n\n"
        "f\t1 2    3   # comment\n"
        "f 1 2 3");  // no final newline
    ASSERT_EQ(m.positions.size(), 3u);
    EXPECT_EQ(m.positions[1], vec3(1, 0, 0));
    EXPECT_EQ(m.positions[2], vec3(0, 1, 0));
    EXPECT_EQ(m.triangles.size(), 2u);
}

TEST(ObjLexical, ByteOrderMarksAndUtf16) {
    const Mesh bom = parse("\xEF\xBB\xBFv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    EXPECT_EQ(bom.triangles.size(), 1u);

    // Encode as UTF-16 (ASCII plus U+00E9) in both byte orders.
    for (bool big : {true, false}) {
        const Mesh m = parse(raykit::test::utf16_with_bom("v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\ng caf\xC3\xA9\r\nf 1 2 3\r\n", big));
        EXPECT_EQ(m.triangles.size(), 1u);
        ASSERT_EQ(m.groups.size(), 1u);
        EXPECT_EQ(m.groups[0].name, "caf\xC3\xA9");
    }
    expect_obj_error(std::string_view("\xFE\xFF\x00", 3), 0, "UTF-16");
}

TEST(ObjLexical, UnknownKeywordsAreIgnored) {
    const Mesh m = parse(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
        "vp 0.5 0.5\n"
        "s 1\ns off\n"
        "l 1 2 3\n"
        "p 1 2\n"
        "c 1 2 3 4\n"
        "curv 0 1 1 2\ncstype bezier\ndeg 3\nparm u 0 1\nend\n"
        "mg 1\nlod 1\nbevel on\nusemap x\nmaplib a.map\n"
        "vw 1 2 0.5\nfoo bar baz\n"
        "f 1 2 3\n");
    EXPECT_EQ(m.triangles.size(), 1u);
    EXPECT_TRUE(m.warnings.empty());
}

// ------------------------------------------------------------------ groups and materials

TEST(ObjGroups, ObjectsAndGroupsCoverTriangleRuns) {
    const Mesh m = parse(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
        "f 1 2 3\n"  // before any o/g: in neither list
        "o first object\n"
        "g  group one  \n"
        "f 1 2 3 4\n"
        "g\n"  // unnamed group
        "f 1 2 3\n"
        "o second\n"
        "g g3\n"
        "g g4\n"  // empty group
        "f 2 3 4\n");
    expect_valid_mesh(m);
    ASSERT_EQ(m.triangles.size(), 5u);
    ASSERT_EQ(m.objects.size(), 2u);
    EXPECT_EQ(m.objects[0].name, "first object");
    EXPECT_EQ(m.objects[0].first_triangle, 1u);
    EXPECT_EQ(m.objects[0].triangle_count, 3u);
    EXPECT_EQ(m.objects[1].name, "second");
    EXPECT_EQ(m.objects[1].first_triangle, 4u);
    EXPECT_EQ(m.objects[1].triangle_count, 1u);
    ASSERT_EQ(m.groups.size(), 4u);
    EXPECT_EQ(m.groups[0].name, "group one");
    EXPECT_EQ(m.groups[0].first_triangle, 1u);
    EXPECT_EQ(m.groups[0].triangle_count, 2u);
    EXPECT_EQ(m.groups[1].name, "");
    EXPECT_EQ(m.groups[1].first_triangle, 3u);
    EXPECT_EQ(m.groups[1].triangle_count, 1u);
    EXPECT_EQ(m.groups[2].name, "g3");
    EXPECT_EQ(m.groups[2].triangle_count, 0u);
    EXPECT_EQ(m.groups[3].name, "g4");
    EXPECT_EQ(m.groups[3].first_triangle, 4u);
    EXPECT_EQ(m.groups[3].triangle_count, 1u);
}

TEST(ObjMaterials, UsemtlAssignsMaterialsPerTriangle) {
    TempDir dir;
    dir.write("m.mtl",
              "newmtl red\nKd 1 0 0\n"
              "newmtl  with  spaces \nKd 0 1 0\n");
    const Mesh m = parse(
        "mtllib m.mtl\n"
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
        "f 1 2 3\n"
        "usemtl red\n"
        "f 1 2 3 4\n"
        "usemtl   with  spaces  \n"
        "f 1 2 3\n"
        "usemtl nope\n"
        "f 1 2 3\n"
        "usemtl red\n"
        "f 2 3 4\n"
        "usemtl\n"  // no name: back to none
        "f 2 3 4\n"
        "usemtl nope\n"  // warned once only
        "f 2 3 4\n",
        dir.path());
    expect_valid_mesh(m);
    ASSERT_EQ(m.materials.size(), 2u);
    EXPECT_EQ(m.materials[0].name, "red");
    EXPECT_EQ(m.materials[1].name, "with  spaces");
    EXPECT_EQ(m.material_ids,
              (std::vector<std::uint32_t>{kNoMaterial, 0, 0, 1, kNoMaterial, 0, kNoMaterial, kNoMaterial}));
    ASSERT_EQ(m.warnings.size(), 1u);
    EXPECT_NE(m.warnings[0].find("fixture.obj:11:"), std::string::npos) << m.warnings[0];
    EXPECT_NE(m.warnings[0].find("'nope'"), std::string::npos) << m.warnings[0];
}

TEST(ObjMaterials, HashSignsInNamesAreNotComments) {
    TempDir dir;
    dir.write("m.mtl", "newmtl Material_#353\nKd 1 0 0 # red\nmap_Kd tex#1.png\n# newmtl commented\n");
    const Mesh m = parse(
        "mtllib m.mtl # a comment\n"
        "v 0 0 0 # first\nv 1 0 0\nv 0 1 0\n"
        "g part #1\n"
        "o Object029_T\xC3\xA9rh\xC3\xA1l\xC3\xB3_Material_#\n"
        "usemtl Material_#353\n"
        "f 1 2 3 # a triangle\n",
        dir.path());
    ASSERT_EQ(m.materials.size(), 1u);
    EXPECT_EQ(m.materials[0].name, "Material_#353");
    EXPECT_EQ(m.materials[0].kd, vec3(1, 0, 0));
    EXPECT_EQ(fs::path(m.materials[0].map_kd), dir.path() / "tex#1.png");
    EXPECT_EQ(m.material_ids, std::vector<std::uint32_t>{0});
    ASSERT_EQ(m.groups.size(), 1u);
    EXPECT_EQ(m.groups[0].name, "part #1");
    ASSERT_EQ(m.objects.size(), 1u);
    EXPECT_EQ(m.objects[0].name, "Object029_T\xC3\xA9rh\xC3\xA1l\xC3\xB3_Material_#");
    EXPECT_TRUE(m.warnings.empty()) << m.warnings[0];
}

TEST(ObjMaterials, UsemtlBeforeMtllibIsResolvedAtTheEnd) {
    TempDir dir;
    dir.write("late.mtl", "newmtl late\nKd 0.5 0.5 0.5\n");
    const Mesh m = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl late\nf 1 2 3\nmtllib late.mtl\n", dir.path());
    EXPECT_EQ(m.material_ids, std::vector<std::uint32_t>{0});
    EXPECT_TRUE(m.warnings.empty());
}

TEST(ObjMaterials, SeveralLibrariesOnOneLineAndOnSeveralLines) {
    TempDir dir;
    dir.write("a.mtl", "newmtl a\nKd 1 0 0\nnewmtl shared\nKd 1 1 1\n");
    dir.write("b.mtl", "newmtl b\nKd 0 1 0\nnewmtl shared\nKd 0 0 0\n");
    dir.write("sub dir/c d.mtl", "newmtl c\nKd 0 0 1\n");
    dir.write("e f.mtl", "newmtl e\n");
    const Mesh m = parse(
        "mtllib a.mtl  b.mtl\tmissing.mtl\n"
        "mtllib sub dir/c d.mtl\n"   // whole rest of line names a file
        "mtllib a.mtl e\\ f.mtl\n"  // a.mtl again (loaded once), escaped space
        "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
        "usemtl b\nf 1 2 3\nusemtl c\nf 1 2 3\nusemtl shared\nf 1 2 3\nusemtl e\nf 1 2 3\n",
        dir.path());
    ASSERT_EQ(m.materials.size(), 6u);
    EXPECT_EQ(m.materials[0].name, "a");
    EXPECT_EQ(m.materials[2].name, "b");
    EXPECT_EQ(m.materials[4].name, "c");
    EXPECT_EQ(m.materials[5].name, "e");
    ASSERT_EQ(m.material_ids.size(), 4u);
    EXPECT_EQ(material_name(m, 0), "b");
    EXPECT_EQ(material_name(m, 1), "c");
    EXPECT_EQ(m.material_ids[2], 1u);  // first definition of "shared" (a.mtl) wins
    EXPECT_EQ(m.materials[1].kd, vec3(1));
    EXPECT_EQ(material_name(m, 3), "e");
    ASSERT_EQ(m.warnings.size(), 1u);
    EXPECT_NE(m.warnings[0].find("fixture.obj:1:"), std::string::npos) << m.warnings[0];
    EXPECT_NE(m.warnings[0].find("missing.mtl"), std::string::npos) << m.warnings[0];
}

TEST(ObjMaterials, MissingLibraryIsAWarningNotAnError) {
    TempDir dir;
    const fs::path obj = dir.write("scene.obj", "mtllib nowhere.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n");
    Mesh m;
    ASSERT_NO_THROW(m = raykit::load_obj(obj));
    EXPECT_EQ(m.triangles.size(), 1u);
    EXPECT_TRUE(m.materials.empty());
    EXPECT_EQ(m.material_ids, std::vector<std::uint32_t>{kNoMaterial});
    ASSERT_EQ(m.warnings.size(), 2u);
    EXPECT_NE(m.warnings[0].find(obj.string() + ":1:"), std::string::npos) << m.warnings[0];
    EXPECT_NE(m.warnings[0].find("nowhere.mtl"), std::string::npos) << m.warnings[0];
    EXPECT_NE(m.warnings[1].find(obj.string() + ":5:"), std::string::npos) << m.warnings[1];
    // A directory with the library's name is "not found" too.
    fs::create_directories(dir.path() / "dir.mtl");
    const Mesh d = parse("mtllib dir.mtl\n", dir.path());
    ASSERT_EQ(d.warnings.size(), 2u);  // not found; no triangles
    EXPECT_NE(d.warnings[0].find("dir.mtl"), std::string::npos) << d.warnings[0];
}

TEST(ObjMaterials, LoadMaterialsFalseSkipsLibraries) {
    TempDir dir;
    dir.write("m.mtl", "newmtl red\n");
    const Mesh m = parse("mtllib m.mtl missing.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n", dir.path(),
                         raykit::ObjOptions{false});
    EXPECT_TRUE(m.materials.empty());
    EXPECT_EQ(m.material_ids, std::vector<std::uint32_t>{kNoMaterial});
    EXPECT_TRUE(m.warnings.empty());
}

TEST(ObjMaterials, MalformedLibraryThrowsNamingTheMtlFile) {
    TempDir dir;
    const fs::path mtl = dir.write("bad.mtl", "newmtl a\r\nKd 1 0 0\r\n\r\nKs 1 x 1\r\n");
    expect_error([&] { parse("mtllib bad.mtl\n", dir.path()); }, mtl.string(), 4, "malformed number 'x'");
}

// ------------------------------------------------------------------ MTL

TEST(Mtl, AllSupportedStatementsAndDefaults) {
    const std::vector<raykit::Material> mats = raykit::parse_mtl(
        "# comment\n"
        "Kd 1 1 1\n"  // before any newmtl: ignored
        "newmtl full\n"
        "  Ka 0.1 0.2 0.3\n"
        "\tKd 0.4 0.5 0.6\n"
        "Ks 0.7 0.8 0.9\n"
        "Ke 1 2 3\n"
        "Ns 96.5\n"
        "Ni 1.45\n"
        "d 0.25\n"
        "illum 7\n"
        "map_Kd tex.png\n"
        "Tf 1 1 1\nKt 0 0 0\nmap_Ks spec.png\nbump -bm 2 b.png\nPr 0.5\nrefl -type sphere r.png\n"
        "newmtl defaults\n"
        "newmtl grey\n"
        "Kd 0.5\n"
        "Ka spectral file.rfl 1.0\n"
        "Ks xyz 1 1 1\n",
        "lib.mtl", "/base");
    ASSERT_EQ(mats.size(), 3u);
    const raykit::Material& f = mats[0];
    EXPECT_EQ(f.name, "full");
    EXPECT_EQ(f.ka, vec3(0.1f, 0.2f, 0.3f));
    EXPECT_EQ(f.kd, vec3(0.4f, 0.5f, 0.6f));
    EXPECT_EQ(f.ks, vec3(0.7f, 0.8f, 0.9f));
    EXPECT_EQ(f.ke, vec3(1, 2, 3));
    EXPECT_EQ(f.ns, 96.5f);
    EXPECT_EQ(f.ni, 1.45f);
    EXPECT_EQ(f.d, 0.25f);
    EXPECT_EQ(f.illum, 7);
    EXPECT_EQ(f.map_kd, (fs::path("/base") / "tex.png").string());
    const raykit::Material& d = mats[1];
    const raykit::Material def;
    EXPECT_EQ(d.name, "defaults");
    EXPECT_EQ(d.kd, def.kd);
    EXPECT_EQ(d.ka, def.ka);
    EXPECT_EQ(d.d, 1.0f);
    EXPECT_EQ(d.illum, 2);
    EXPECT_EQ(d.map_kd, "");
    EXPECT_EQ(mats[2].kd, vec3(0.5f));
    EXPECT_EQ(mats[2].ka, def.ka);  // spectral: ignored
    EXPECT_EQ(mats[2].ks, def.ks);  // xyz: ignored
}

TEST(Mtl, TransparencyTrAndD) {
    const std::vector<raykit::Material> mats = raykit::parse_mtl(
        "newmtl tr_only\nTr 0.25\n"
        "newmtl d_then_tr\nd 0.75\nTr 0.5\n"
        "newmtl tr_then_d\nTr 0.5\nd 0.75\n"
        "newmtl halo\nd -halo 0.5\n"
        "newmtl last_tr\nTr 0.1\n",
        "t.mtl", "");
    ASSERT_EQ(mats.size(), 5u);
    EXPECT_FLOAT_EQ(mats[0].d, 0.75f);
    EXPECT_FLOAT_EQ(mats[1].d, 0.75f);
    EXPECT_FLOAT_EQ(mats[2].d, 0.75f);
    EXPECT_FLOAT_EQ(mats[3].d, 0.5f);
    EXPECT_FLOAT_EQ(mats[4].d, 0.9f);
}

TEST(Mtl, TextureOptionsAndFileNamesWithSpaces) {
    const std::vector<raykit::Material> mats = raykit::parse_mtl(
        "newmtl a\nmap_Kd -s 1 1 1 -o 0 0 0 -bm 1 -clamp on my texture.png\n"
        "newmtl b\nmap_Kd -o 0.1 diffuse.jpg\n"
        "newmtl c\nmap_Kd -s 0.1 0.2 d 2.png  \n"
        "newmtl d\nmap_Kd -blendu on -blendv off -boost 2 -cc off -imfchan r -mm 0 1 -t 1 2 3 "
        "-texres 512 -type sphere -colorspace sRGB x.tga\n"
        "newmtl e\nmap_Kd -mm 0.5 t.png\n"
        "newmtl f\nmap_Kd sub/dir/file name.png\n"
        "newmtl g\nmap_Kd\n",
        "lib.mtl", "/textures");
    ASSERT_EQ(mats.size(), 7u);
    auto at = [](const char* f) { return (fs::path("/textures") / f).string(); };
    EXPECT_EQ(mats[0].map_kd, at("my texture.png"));
    EXPECT_EQ(mats[1].map_kd, at("diffuse.jpg"));
    EXPECT_EQ(mats[2].map_kd, at("d 2.png"));
    EXPECT_EQ(mats[3].map_kd, at("x.tga"));
    EXPECT_EQ(mats[4].map_kd, at("t.png"));
    EXPECT_EQ(mats[5].map_kd, at("sub/dir/file name.png"));
    EXPECT_EQ(mats[6].map_kd, "");
}

TEST(Mtl, TexturePathIsRelativeToTheMtlFile) {
    TempDir dir;
    dir.write("materials/lib.mtl", "newmtl m\nmap_Kd -clamp on tex/albedo map.png\n");
    const fs::path obj = dir.write("scene.obj", "mtllib materials/lib.mtl\n");
    const Mesh m = raykit::load_obj(obj);
    ASSERT_EQ(m.materials.size(), 1u);
    EXPECT_EQ(fs::path(m.materials[0].map_kd), dir.path() / "materials" / "tex/albedo map.png");
    const std::vector<raykit::Material> direct = raykit::load_mtl(dir.path() / "materials/lib.mtl");
    ASSERT_EQ(direct.size(), 1u);
    EXPECT_EQ(direct[0].map_kd, m.materials[0].map_kd);
}

TEST(Mtl, MalformedStatements) {
    struct Case {
        const char* text;
        std::size_t line;
        const char* fragment;
    };
    const Case cases[] = {
        {"newmtl a\nKd 1 x 1\n", 2, "malformed number 'x'"},
        {"newmtl a\nKd 1 1\n", 2, "'Kd' needs 1 or 3 values"},
        {"newmtl a\nKa\n", 2, "'Ka' needs 1 or 3 values"},
        {"newmtl a\n\nNs abc\n", 3, "malformed number 'abc' in 'Ns'"},
        {"newmtl a\nNi\n", 2, "'Ni' needs a value"},
        {"newmtl a\nd nan\n", 2, "non-finite"},
        {"newmtl a\nTr 1e99\n", 2, "overflows"},
        {"newmtl a\nillum two\n", 2, "malformed illum"},
        {"newmtl a\r\n# c \\\r\n more comment\r\nKe 1 2 3x\r\n", 4, "malformed number '3x'"},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.text);
        expect_error([&] { raykit::parse_mtl(c.text, "lib.mtl", ""); }, "lib.mtl", c.line, c.fragment);
    }
    expect_error([] { raykit::load_mtl("/nonexistent/raykit/lib.mtl"); }, "/nonexistent/raykit/lib.mtl", 0,
                 "cannot open");
}

// ------------------------------------------------------------------ errors

TEST(ObjErrors, MalformedNumbers) {
    const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    expect_obj_error(tri + "v 1 2 x\n", 4, "malformed number 'x' in 'v'");
    expect_obj_error("v 1 2\n", 1, "'v' needs at least 3 numbers, got 2");
    expect_obj_error("v\n", 1, "'v' needs at least 3 numbers, got 0");
    expect_obj_error("\n\nv 1 2 3x\n", 3, "malformed number '3x'");
    expect_obj_error("v 1 2 3 x\n", 1, "malformed number 'x'");  // extras must be numbers too
    expect_obj_error("v +-1 0 0\n", 1, "malformed number '+-1'");
    expect_obj_error("v --1 0 0\n", 1, "malformed number '--1'");
    expect_obj_error("v 1e 0 0\n", 1, "malformed number '1e'");
    expect_obj_error("v 1.5e+ 0 0\n", 1, "malformed number '1.5e+'");
    expect_obj_error("v 0x10 0 0\n", 1, "malformed number '0x10'");
    expect_obj_error("v . 0 0\n", 1, "malformed number '.'");
    expect_obj_error("v 1,5 0 0\n", 1, "malformed number '1,5'");
    expect_obj_error("v 3.1+e2 0 0\n", 1, "malformed number '3.1+e2'");
    expect_obj_error("v 1 1 1\nvt\n", 2, "'vt' needs at least 1 numbers, got 0");
    expect_obj_error("vt 0.5 y\n", 1, "malformed number 'y' in 'vt'");
    expect_obj_error("vn 0 1\n", 1, "'vn' needs at least 3 numbers, got 2");
    expect_obj_error("vn 0 1 z\n", 1, "malformed number 'z' in 'vn'");
}

TEST(ObjErrors, NonFiniteAndOverflowingNumbers) {
    expect_obj_error("v nan 0 0\n", 1, "non-finite number 'nan'");
    expect_obj_error("v 0 -nan 0\n", 1, "non-finite number '-nan'");
    expect_obj_error("v 0 0 NaN\n", 1, "non-finite number 'NaN'");
    expect_obj_error("v inf 0 0\n", 1, "non-finite number 'inf'");
    expect_obj_error("v 0 -Infinity 0\n", 1, "non-finite number '-Infinity'");
    expect_obj_error("v 0 0 +inf\n", 1, "non-finite number '+inf'");
    expect_obj_error("v nan(0x1) 0 0\n", 1, "non-finite number 'nan(0x1)'");
    expect_obj_error("v nope 0 0\n", 1, "malformed number 'nope'");
    expect_obj_error("v 0 info 0\n", 1, "malformed number 'info'");
    expect_obj_error("v 1e39 0 0\n", 1, "overflows a float");
    expect_obj_error("v 0 -3.5e38 0\n", 1, "overflows a float");
    expect_obj_error("v 0 0 1e400\n", 1, "overflows a float");
    expect_obj_error("vn 0 0 1e39\n", 1, "overflows a float in 'vn'");
    expect_obj_error("vt 1e39 0\n", 1, "overflows a float in 'vt'");
    // 1.#IND (MSVC) reads as "1." followed by a comment: too few numbers.
    expect_obj_error("v 1.#IND -1.#IND 1.#IND\n", 1, "needs at least 3 numbers, got 1");
}

TEST(ObjErrors, BadFaces) {
    const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n";  // lines 1-5
    expect_obj_error(tri + "f 1 2\n", 6, "at least 3 corners, got 2");
    expect_obj_error(tri + "f\n", 6, "at least 3 corners, got 0");
    expect_obj_error(tri + "f 0 1 2\n", 6, "vertex index 0");
    expect_obj_error(tri + "f 1/0 2/1 3/1\n", 6, "texture coordinate index 0");
    expect_obj_error(tri + "f 1//1 2//0 3//1\n", 6, "normal index 0");
    expect_obj_error(tri + "f 1 2 4\n", 6, "vertex index 4 in face corner '4' is out of range");
    expect_obj_error(tri + "f -4 -2 -1\n", 6, "relative vertex index -4");
    expect_obj_error(tri + "f 1/2 2/1 3/1\n", 6, "texture coordinate index 2");
    expect_obj_error(tri + "f 1/-2 2/1 3/1\n", 6, "relative texture coordinate index -2");
    expect_obj_error(tri + "f 1//1 2//2 3//1\n", 6, "normal index 2");
    expect_obj_error(tri + "f 1//-2 2//1 3//1\n", 6, "relative normal index -2");
    expect_obj_error(tri + "f 1 2 99999999999999999999\n", 6, "out of range");
    // Indices may not refer to elements defined further down.
    expect_obj_error("v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\n", 3, "vertex index 3");
    for (const char* corner : {"1/", "1/1/", "1//", "/1", "1/1/1/1", "a", "1x", "1/x", "1//x", "1 /1", "+"}) {
        SCOPED_TRACE(corner);
        const std::string text = tri + "f 2 3 " + corner + "\n";
        const std::optional<ParseError> e = error_of([&] { parse(text); });
        ASSERT_TRUE(e.has_value());
        EXPECT_EQ(e->line(), 6u) << e->what();
    }
    expect_obj_error(tri + "f 1 2 1/\n", 6, "malformed face corner '1/'");
}

TEST(ObjErrors, UnreadableFiles) {
    expect_error([] { raykit::load_obj("/nonexistent/raykit/none.obj"); }, "/nonexistent/raykit/none.obj", 0,
                 "cannot open");
    TempDir dir;
    expect_error([&] { raykit::load_obj(dir.path()); }, dir.path().string(), 0, "is a directory");
}

TEST(ObjErrors, LoadObjNamesTheFile) {
    TempDir dir;
    const fs::path obj = dir.write("broken.obj", "# ok\r\nv 0 0 0\r\nv 1 0 0\r\nf 1 2 3\r\n");
    expect_error([&] { raykit::load_obj(obj); }, obj.string(), 4, "vertex index 3");
}

// ------------------------------------------------------------------ tinyobjloader oracle

/// One triangle corner in a loader-independent form.
struct RefCorner {
    vec3 p;
    std::optional<vec3> n;
    std::optional<vec2> t;
};
struct RefTriangle {
    RefCorner c[3];
    std::string material;
};

/// tinyobjloader's triangles. With `fan`, the file was read with
/// triangulate = false and every polygon is fanned here like raykit does.
std::vector<RefTriangle> tinyobj_triangles(const tinyobj::ObjReader& r, bool fan) {
    const tinyobj::attrib_t& a = r.GetAttrib();
    std::vector<RefTriangle> out;
    auto corner = [&](const tinyobj::index_t& i) {
        RefCorner c;
        c.p = vec3(a.vertices[3 * i.vertex_index], a.vertices[3 * i.vertex_index + 1],
                   a.vertices[3 * i.vertex_index + 2]);
        if (i.normal_index >= 0) {
            c.n = vec3(a.normals[3 * i.normal_index], a.normals[3 * i.normal_index + 1],
                       a.normals[3 * i.normal_index + 2]);
        }
        if (i.texcoord_index >= 0) {
            c.t = vec2(a.texcoords[2 * i.texcoord_index], a.texcoords[2 * i.texcoord_index + 1]);
        }
        return c;
    };
    for (const tinyobj::shape_t& s : r.GetShapes()) {
        std::size_t offset = 0;
        for (std::size_t f = 0; f < s.mesh.num_face_vertices.size(); ++f) {
            const std::size_t n = s.mesh.num_face_vertices[f];
            const int mat = s.mesh.material_ids[f];
            const std::string name = mat >= 0 ? r.GetMaterials()[mat].name : std::string();
            if (!fan) {
                EXPECT_EQ(n, 3u);
            }
            for (std::size_t i = 1; i + 1 < n; ++i) {
                RefTriangle t;
                t.c[0] = corner(s.mesh.indices[offset]);
                t.c[1] = corner(s.mesh.indices[offset + i]);
                t.c[2] = corner(s.mesh.indices[offset + i + 1]);
                t.material = name;
                out.push_back(t);
            }
            offset += n;
        }
    }
    return out;
}

/// Equal up to the last bits: tinyobjloader's number parser is not correctly
/// rounded, raykit's (std::from_chars) is.
bool near(float a, float b) {
    return a == b || std::fabs(a - b) <= 4.0f * FLT_EPSILON * std::max(std::fabs(a), std::fabs(b));
}
bool near(const vec3& a, const vec3& b) { return near(a.x, b.x) && near(a.y, b.y) && near(a.z, b.z); }
bool near(const vec2& a, const vec2& b) { return near(a.x, b.x) && near(a.y, b.y); }

std::string str(const vec3& v) {
    std::ostringstream s;
    s << "(" << v.x << ", " << v.y << ", " << v.z << ")";
    return s.str();
}
std::string str(const vec2& v) {
    std::ostringstream s;
    s << "(" << v.x << ", " << v.y << ")";
    return s.str();
}

/// The first difference between raykit's mesh and tinyobjloader's triangles,
/// or "" when they agree.
std::string compare(const Mesh& m, const std::vector<RefTriangle>& ref) {
    if (m.triangles.size() != ref.size()) {
        return "triangle count " + std::to_string(m.triangles.size()) + " vs tinyobj " + std::to_string(ref.size());
    }
    for (std::size_t t = 0; t < ref.size(); ++t) {
        const std::string where = "triangle " + std::to_string(t);
        for (int c = 0; c < 3; ++c) {
            const std::uint32_t v = m.triangles[t].v[c];
            const RefCorner& rc = ref[t].c[c];
            const std::string at = where + " corner " + std::to_string(c) + ": ";
            if (!near(m.positions[v], rc.p)) return at + "position " + str(m.positions[v]) + " vs " + str(rc.p);
            if (rc.n) {
                if (m.normals.empty()) return at + "raykit has no normals";
                if (!near(m.normals[v], *rc.n)) return at + "normal " + str(m.normals[v]) + " vs " + str(*rc.n);
            } else if (!m.normals.empty() && m.normals[v] != vec3(0)) {
                return at + "raykit has a normal where tinyobj has none";
            }
            if (rc.t) {
                if (m.texcoords.empty()) return at + "raykit has no texcoords";
                if (!near(m.texcoords[v], *rc.t)) return at + "texcoord " + str(m.texcoords[v]) + " vs " + str(*rc.t);
            } else if (!m.texcoords.empty() && m.texcoords[v] != vec2(0)) {
                return at + "raykit has a texcoord where tinyobj has none";
            }
        }
        if (material_name(m, t) != ref[t].material) {
            return where + ": material '" + material_name(m, t) + "' vs tinyobj '" + ref[t].material + "'";
        }
    }
    return "";
}

fs::path shared_data_dir() {
#ifdef RAYKIT_SHARED_DATA_DIR
    return fs::path(RAYKIT_SHARED_DATA_DIR);
#else
    return fs::path(__FILE__).parent_path().parent_path().parent_path() / "shared" / "data";
#endif
}
const fs::path kAssimpDir = "/usr/share/assimp/models/OBJ";

/// Every corpus file, as a key naming its source ("shared/..." or "assimp/...").
struct CorpusFile {
    std::string key;
    fs::path path;
};
void PrintTo(const CorpusFile& f, std::ostream* os) { *os << f.key; }

std::vector<CorpusFile> corpus_files() {
    std::vector<CorpusFile> out;
    auto scan = [&](const fs::path& root, const std::string& prefix) {
        std::error_code ec;
        if (!fs::is_directory(root, ec)) return;
        for (auto it = fs::recursive_directory_iterator(root, ec); !ec && it != fs::recursive_directory_iterator();
             it.increment(ec)) {
            if (it->is_regular_file() && it->path().extension() == ".obj") {
                out.push_back({prefix + fs::relative(it->path(), root).generic_string(), it->path()});
            }
        }
    };
    scan(shared_data_dir() / "obj", "shared/");
    scan(kAssimpDir, "assimp/");
    std::sort(out.begin(), out.end(), [](const CorpusFile& a, const CorpusFile& b) { return a.key < b.key; });
    return out;
}

enum class Expect {
    raykit_rejects,  // raykit throws ParseError, tinyobjloader accepts the file
    both_reject,     // both refuse the file
    differ,          // both accept it, the results differ
};
struct Known {
    Expect expect;
    const char* reason;
};

/// Every corpus file where raykit and tinyobjloader (read with triangulate =
/// false, polygons fanned by the test) do not agree. A file not listed here
/// must load in both and give the same triangles.
const std::map<std::string, Known>& known_differences() {
    static const std::map<std::string, Known> k = {
        {"shared/tinyobj_models/catmark_torus_creases0.obj",
         {Expect::raykit_rejects, "faces use vn 1 but the file has no vn line (tinyobj warns and drops normals)"}},
        {"shared/tinyobj_models/invalid-face-definition.obj",
         {Expect::raykit_rejects, "faces with 1 and 2 corners (tinyobj skips them with a warning)"}},
        {"shared/tinyobj_models/invalid-relative-texture-index.obj",
         {Expect::raykit_rejects, "face uses vertex 1 but no v is defined (tinyobj warns, keeps the face)"}},
        {"shared/tinyobj_models/invalid-relative-vertex-index.obj",
         {Expect::raykit_rejects, "relative index -4 with no vertex defined (tinyobj accepts it silently)"}},
        {"shared/tinyobj_models/smoothing-group-two-squares.obj",
         {Expect::raykit_rejects, "its vn lines are commented out but faces use normals 1-5 (tinyobj warns)"}},
        {"shared/tinyobj_models/test-nan.obj",
         {Expect::raykit_rejects, "nan / inf coordinates, rejected by raykit (tinyobj stores them)"}},
        {"shared/tinyobj_models/issue-140-zero-face-idx.obj", {Expect::both_reject, "face index 0"}},
        {"assimp/number_formats.obj",
         {Expect::raykit_rejects, "'3.1+e2' is not a number (tinyobj reads 3.1 and drops the rest)"}},
        {"shared/helix/obj_format_tests/line_continuation_empty_continuation.obj",
         {Expect::differ, "'\\' line continuations: tinyobj does not join them"}},
        {"shared/helix/obj_format_tests/line_continuation_empty_line.obj",
         {Expect::differ, "'\\' line continuations: tinyobj does not join them"}},
        {"shared/helix/obj_format_tests/line_continuation_multiple_breaks.obj",
         {Expect::differ, "'\\' line continuations: tinyobj does not join them"}},
        {"shared/helix/obj_format_tests/line_continuation_single.obj",
         {Expect::differ, "'\\' line continuations: tinyobj does not join them"}},
        {"assimp/box_UTF16BE.obj", {Expect::differ, "UTF-16 text: raykit converts it, tinyobj finds no faces"}},
        {"assimp/box_longline.obj",
         {Expect::differ, "a 936-corner face: tinyobj reads only 168 of its corners, raykit fans all 936"}},
        {"assimp/box_mat_with_spaces.obj",
         {Expect::differ, "usemtl name with spaces: tinyobj keeps only its first word and finds no material"}},
        {"assimp/space_in_material_name.obj",
         {Expect::differ, "usemtl name with spaces: tinyobj keeps only its first word and finds no material"}},
    };
    return k;
}

/// Files whose tinyobjloader triangulation (triangulate = true) is not a fan
/// from the first corner: 2.0.0rc10 cuts quads along their shorter diagonal
/// (on a tie or a shorter 1-3 diagonal that gives (0,1,3), (1,2,3)) and
/// ear-clips larger polygons. Every other file that both accept must give the
/// same triangles with triangulate = true as well.
constexpr const char* kQuadSplit = "quads: tinyobj cuts along the shorter diagonal, not the 0-2 fan diagonal";
constexpr const char* kEarClip = "polygons with more than 4 corners: tinyobj ear-clips them";
const std::map<std::string, const char*>& tinyobj_triangulation_differs() {
    static const std::map<std::string, const char*> k = {
        {"assimp/box.obj", kQuadSplit},
        {"assimp/box_without_lineending.obj", kQuadSplit},
        {"assimp/concave_polygon.obj", kEarClip},
        {"assimp/testmixed.obj", kQuadSplit},
        {"shared/helix/cornell_box/cornell_box.obj", kQuadSplit},
        {"shared/tinyobj_models/cornell_box.obj", kQuadSplit},
        {"shared/tinyobj_models/cornell_box_multimaterial.obj", kQuadSplit},
        {"shared/tinyobj_models/cube-vertex-w-component.obj", kQuadSplit},
        {"shared/tinyobj_models/cube-vertexcol.obj", kQuadSplit},
        {"shared/tinyobj_models/cube.obj", kQuadSplit},
        {"shared/tinyobj_models/issue-248-texres-texopt.obj", kQuadSplit},
        {"shared/tinyobj_models/issue-295-trianguation-failure.obj", kQuadSplit},
        {"shared/tinyobj_models/issue-319-002.obj", kEarClip},
        {"shared/tinyobj_models/issue-319-003.obj", kEarClip},
        {"shared/tinyobj_models/issue-330.obj", kQuadSplit},
        {"shared/tinyobj_models/missing_material_file.obj", kQuadSplit},
        {"shared/tinyobj_models/mtl filename with whitespace issue46.obj", kQuadSplit},
        {"shared/tinyobj_models/no_material.obj", kQuadSplit},
        {"shared/tinyobj_models/pbr-mat-ext.obj", kQuadSplit},
        {"shared/tinyobj_models/refl.obj", kQuadSplit},
        {"shared/tinyobj_models/skin-weight.obj", kQuadSplit},
        {"shared/tinyobj_models/smoothing-normal.obj", kQuadSplit},
        {"shared/tinyobj_models/texture-filename-with-whitespace.obj", kQuadSplit},
        {"shared/tinyobj_models/usemtl-issue-104.obj", kQuadSplit},
    };
    return k;
}

class ObjOracle : public ::testing::TestWithParam<CorpusFile> {};

TEST_P(ObjOracle, MatchesTinyobjloader) {
    const CorpusFile& file = GetParam();
    if (file.path.empty()) GTEST_SKIP() << "no OBJ corpus found (shared/data/obj or " << kAssimpDir << ")";
    SCOPED_TRACE(file.path.string());

    std::optional<Mesh> mesh;
    std::optional<ParseError> error;
    try {
        mesh = raykit::load_obj(file.path);
    } catch (const ParseError& e) {
        error = e;
    }
    tinyobj::ObjReader reader;
    tinyobj::ObjReaderConfig config;
    config.triangulate = false;
    const bool tiny_ok = reader.ParseFromFile(file.path.string(), config);

    const auto& known = known_differences();
    const auto it = known.find(file.key);
    if (it != known.end()) {
        RecordProperty("known_difference", it->second.reason);
        switch (it->second.expect) {
            case Expect::raykit_rejects:
            case Expect::both_reject:
                ASSERT_TRUE(error.has_value()) << "listed as rejected by raykit (" << it->second.reason
                                               << ") but it loads";
                EXPECT_EQ(error->file(), file.path.string());
                EXPECT_GT(error->line(), 0u) << error->what();
                EXPECT_EQ(tiny_ok, it->second.expect == Expect::raykit_rejects) << reader.Error();
                return;
            case Expect::differ:
                ASSERT_FALSE(error.has_value()) << error->what();
                ASSERT_TRUE(tiny_ok) << reader.Error();
                EXPECT_NE(compare(*mesh, tinyobj_triangles(reader, true)), "")
                    << "listed as differing (" << it->second.reason << ") but raykit and tinyobj agree";
                expect_valid_mesh(*mesh);
                return;
        }
    }
    ASSERT_FALSE(error.has_value()) << "raykit rejects a file tinyobj " << (tiny_ok ? "accepts" : "rejects too")
                                    << ": " << error->what();
    ASSERT_TRUE(tiny_ok) << "tinyobj rejects: " << reader.Error();
    expect_valid_mesh(*mesh);
    EXPECT_EQ(compare(*mesh, tinyobj_triangles(reader, true)), "");

    // tinyobj's own triangulation.
    tinyobj::ObjReader tri_reader;
    tinyobj::ObjReaderConfig tri_config;
    tri_config.triangulate = true;
    ASSERT_TRUE(tri_reader.ParseFromFile(file.path.string(), tri_config)) << tri_reader.Error();
    const std::string diff = compare(*mesh, tinyobj_triangles(tri_reader, false));
    const auto& tri_known = tinyobj_triangulation_differs();
    if (const auto t = tri_known.find(file.key); t != tri_known.end()) {
        EXPECT_NE(diff, "") << "listed as triangulated differently (" << t->second << ") but it matches";
    } else {
        EXPECT_EQ(diff, "") << "tinyobj's triangulate = true result differs";
    }
}

std::vector<CorpusFile> oracle_params() {
    std::vector<CorpusFile> files = corpus_files();
    if (files.empty()) files.push_back({"none", {}});
    return files;
}

std::string param_name(const ::testing::TestParamInfo<CorpusFile>& info) {
    std::string s;
    for (char c : info.param.key) s += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
    return s;
}

INSTANTIATE_TEST_SUITE_P(Corpus, ObjOracle, ::testing::ValuesIn(oracle_params()), param_name);

TEST(ObjOracleList, EveryListedFileExists) {
    const std::vector<CorpusFile> files = corpus_files();
    if (files.empty()) GTEST_SKIP() << "no OBJ corpus";
    const bool have_shared = fs::is_directory(shared_data_dir() / "obj");
    const bool have_assimp = fs::is_directory(kAssimpDir);
    auto present = [&](const std::string& key) {
        if ((key.rfind("shared/", 0) == 0 && !have_shared) || (key.rfind("assimp/", 0) == 0 && !have_assimp)) {
            return true;  // that corpus is not installed here
        }
        return std::any_of(files.begin(), files.end(), [&](const CorpusFile& f) { return f.key == key; });
    };
    for (const auto& [key, known] : known_differences()) EXPECT_TRUE(present(key)) << key;
    for (const auto& [key, reason] : tinyobj_triangulation_differs()) EXPECT_TRUE(present(key)) << key;
}

// Specific facts about corpus files, beyond agreeing with tinyobjloader.
TEST(ObjCorpus, StanfordBunny) {
    const fs::path p = shared_data_dir() / "obj/stanford_bunny/stanford-bunny.obj";
    if (!fs::exists(p)) GTEST_SKIP() << p << " not found";
    const Mesh m = raykit::load_obj(p);
    EXPECT_EQ(m.triangles.size(), 69451u);
    EXPECT_EQ(m.positions.size(), 34834u);  // == its v lines: all referenced, file order
    EXPECT_TRUE(m.normals.empty());
    EXPECT_TRUE(m.texcoords.empty());
}

TEST(ObjCorpus, HelixContinuationFiles) {
    const fs::path dir = shared_data_dir() / "obj/helix/obj_format_tests";
    if (!fs::is_directory(dir)) GTEST_SKIP() << dir << " not found";
    for (const char* name : {"line_continuation_comment.obj", "line_continuation_empty_continuation.obj",
                             "line_continuation_empty_line.obj", "line_continuation_multiple_breaks.obj",
                             "line_continuation_single.obj"}) {
        SCOPED_TRACE(name);
        const Mesh m = raykit::load_obj(dir / name);
        ASSERT_EQ(m.positions.size(), 3u);
        EXPECT_EQ(m.positions[0], vec3(-1, 0, 1));
        EXPECT_EQ(m.positions[1], vec3(1, 0, 1));
        EXPECT_EQ(m.positions[2], vec3(-1, 0, -1));
        EXPECT_EQ(m.triangles.size(), 1u);
    }
}

TEST(ObjCorpus, TinyobjMaterialFiles) {
    const fs::path dir = shared_data_dir() / "obj/tinyobj_models";
    if (!fs::is_directory(dir)) GTEST_SKIP() << dir << " not found";
    {
        const Mesh m = raykit::load_obj(dir / "mtllib-multiple-files-issue-112.obj");
        EXPECT_EQ(m.warnings.size(), 2u);  // two of the three libraries are missing
        ASSERT_EQ(m.materials.size(), 1u);
        EXPECT_EQ(m.material_ids, std::vector<std::uint32_t>{0});
        EXPECT_EQ(fs::path(m.materials[0].map_kd), dir / "tmp.png");
    }
    {
        const Mesh m = raykit::load_obj(dir / "mtl filename with whitespace issue46.obj");
        ASSERT_EQ(m.materials.size(), 1u);  // escaped spaces in the mtllib line
        EXPECT_EQ(m.warnings.size(), 2u);
        EXPECT_EQ(material_name(m, 0), "green");
    }
    {
        const std::vector<raykit::Material> mats = raykit::load_mtl(dir / "tr-and-d-issue-43.mtl");
        ASSERT_EQ(mats.size(), 2u);
        EXPECT_FLOAT_EQ(mats[0].d, 0.75f);
        EXPECT_FLOAT_EQ(mats[1].d, 0.75f);
    }
    {
        const std::vector<raykit::Material> mats = raykit::load_mtl(dir / "texture-options-issue-85.mtl");
        ASSERT_EQ(mats.size(), 3u);
        EXPECT_EQ(fs::path(mats[0].map_kd), dir / "diffuse.jpg");
        EXPECT_EQ(fs::path(mats[1].map_kd), dir / "diffuse.jpg");
        EXPECT_EQ(fs::path(mats[2].map_kd), dir / "diffuse.jpg");
    }
    {
        const std::vector<raykit::Material> mats = raykit::load_mtl(dir / "texture-filename-with-whitespace.mtl");
        EXPECT_EQ(fs::path(mats.at(0).map_kd), dir / "texture 01.png");
    }
    {
        const Mesh m = raykit::load_obj(dir / "issue-356-leading-spaces-newmtl.obj");
        ASSERT_EQ(m.materials.size(), 1u);
        EXPECT_EQ(m.materials[0].name, "aaa");
        ASSERT_EQ(m.warnings.size(), 1u);  // the file has no faces
        EXPECT_NE(m.warnings[0].find("no triangles"), std::string::npos) << m.warnings[0];
    }
}

// ------------------------------------------------------------------ issue 12: bounds and honesty

TEST(ObjScale, ManyTexcoordsPerPositionNumbersVerticesInOrderOfFirstUse) {
    // 8 positions, each used with thousands of distinct (vt, vn) pairs, plus
    // repeated corners. The loader was quadratic here (per-position chains):
    // this file took seconds; it must number vertices exactly as an
    // independent std::map oracle does (order of first use of the triple).
    constexpr int kPositions = 8, kTexcoords = 20000, kNormals = 3, kFaces = 30000;
    std::mt19937 rng(12);
    std::ostringstream text;
    for (int i = 0; i < kPositions; ++i) text << "v " << i << " " << (i % 3) << " " << (i % 2) << "\n";
    for (int i = 0; i < kTexcoords; ++i) text << "vt " << (i % 100) * 0.01 << " " << (i / 100) * 0.005 << "\n";
    for (int i = 0; i < kNormals; ++i) text << "vn " << (i == 0) << " " << (i == 1) << " " << (i == 2) << "\n";
    std::map<std::array<int, 3>, std::uint32_t> first_use;
    std::vector<Tri> expected;
    for (int f = 0; f < kFaces; ++f) {
        text << "f";
        Tri tri{};
        for (int c = 0; c < 3; ++c) {
            const std::array<int, 3> key{int(rng() % kPositions), int(rng() % kTexcoords), int(rng() % kNormals)};
            text << " " << key[0] + 1 << "/" << key[1] + 1 << "/" << key[2] + 1;
            tri[c] = first_use.try_emplace(key, static_cast<std::uint32_t>(first_use.size())).first->second;
        }
        text << "\n";
        expected.push_back(tri);
    }
    const Mesh m = parse(text.str());
    expect_valid_mesh(m);
    ASSERT_EQ(m.positions.size(), first_use.size());
    ASSERT_GT(first_use.size(), 80000u);  // most corners are new: ~11,000 per position
    EXPECT_EQ(triangles_of(m), expected);
    for (const auto& [key, id] : first_use) {
        ASSERT_EQ(m.positions[id], vec3(float(key[0]), float(key[0] % 3), float(key[0] % 2)));
        ASSERT_EQ(m.texcoords[id].x, float((key[1] % 100) * 0.01));
        ASSERT_EQ(m.normals[id][key[2]], 1.0f);
    }
}

TEST(ObjErrors, NulBytesInFileNamesAreErrors) {
    // The OS would see the name cut at the NUL: a different file than the one named.
    TempDir dir;
    dir.write("a", "newmtl red\n");  // what "a\0b.mtl" would have opened
    const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    expect_error([&] { parse(tri + std::string("mtllib a\0b.mtl\n", 15), dir.path()); }, kFixtureName, 5,
                 "NUL byte in file name");
    expect_error([&] { raykit::parse_mtl(std::string("newmtl a\nmap_Kd x\0y.png\n", 24), "m.mtl", dir.path()); },
                 "m.mtl", 2, "NUL byte in file name");
}

TEST(ObjErrors, WhatIsNotARegularFileIsRefusedNamingIt) {
    TempDir dir;
    expect_error([&] { raykit::load_mtl(dir.path()); }, dir.path().string(), 0, "is a directory");
    expect_error([&] { raykit::load_obj(dir.path()); }, dir.path().string(), 0, "is a directory");
    if (fs::exists("/dev/zero")) {  // used to end in std::bad_alloc
        expect_error([] { raykit::load_obj("/dev/zero"); }, "/dev/zero", 0, "not a regular file");
        expect_error([] { raykit::load_mtl("/dev/zero"); }, "/dev/zero", 0, "not a regular file");
    }
    const fs::path fifo = dir.path() / "pipe.obj";
    if (::mkfifo(fifo.c_str(), 0600) == 0) {  // opening it for reading would block forever
        expect_error([&] { raykit::load_obj(fifo); }, fifo.string(), 0, "not a regular file");
    }
}

TEST(ObjLexical, AbsurdlyLongLinesAreRefused) {
    const std::string big(raykit::kMaxLineBytes + 1, '1');
    expect_obj_error("v 0 0 0\nv " + big + " 0 0\n", 2, "line longer than");
    // The limit is on the logical line: continuations count together.
    const std::string half(raykit::kMaxLineBytes / 2 + 1, '1');
    expect_obj_error("# a\nv " + half + " \\\n" + half + " 0\n", 2, "line longer than");
    expect_error([&] { raykit::parse_mtl("newmtl a\nKd " + big + "\n", "m.mtl", {}); }, "m.mtl", 2,
                 "line longer than");
    // Just under the limit is fine (the number overflows, reported as such).
    const std::string fits(raykit::kMaxLineBytes - 8, '1');
    expect_obj_error("v " + fits + " 0 0\n", 1, "overflows a float");
}

TEST(ObjLexical, OneNumberRuleTinyIsZeroHugeIsAnError) {
    const Mesh m = parse("v 1e-46 -1e-46 1e-40\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    EXPECT_EQ(m.positions[0].x, 0.0f);
    EXPECT_TRUE(std::signbit(m.positions[0].y));
    EXPECT_EQ(m.positions[0].z, 1e-40f);
    expect_obj_error("v 1e39 0 0\n", 1, "'1e39' overflows a float");
}

TEST(Mtl, WindowsSeparatorsInTexturePathsAreNormalisedWhenThePathIsMissing) {
    TempDir dir;
    dir.write("tex/Spider Tex.jpg", "x");
    dir.write("odd\\name.png", "x");  // a real file whose name has a backslash: kept as written
    const fs::path mtl = dir.write("m.mtl",
                                   "newmtl a\nmap_Kd .\\tex\\Spider Tex.jpg\n"
                                   "newmtl b\nmap_Kd odd\\name.png\n"
                                   "newmtl c\nmap_Kd -s 1 1 1 tex\\Spider Tex.jpg\n");
    const std::vector<raykit::Material> mats = raykit::load_mtl(mtl);
    ASSERT_EQ(mats.size(), 3u);
    EXPECT_EQ(fs::path(mats[0].map_kd), dir.path() / "tex" / "Spider Tex.jpg");
    EXPECT_TRUE(fs::exists(mats[0].map_kd)) << mats[0].map_kd;
    EXPECT_EQ(fs::path(mats[1].map_kd), dir.path() / "odd\\name.png");
    EXPECT_EQ(fs::path(mats[2].map_kd), dir.path() / "tex" / "Spider Tex.jpg");
}

TEST(Mtl, AssimpSpiderTexturesAreFound) {
    const fs::path obj = "/usr/share/assimp/models/OBJ/spider.obj";
    if (!fs::exists(obj)) GTEST_SKIP() << obj << " not installed";
    const Mesh m = raykit::load_obj(obj);
    int textured = 0;
    for (const raykit::Material& mat : m.materials) {
        if (mat.map_kd.empty()) continue;
        ++textured;
        EXPECT_TRUE(fs::is_regular_file(mat.map_kd)) << mat.name << ": " << mat.map_kd;
    }
    EXPECT_GT(textured, 0);
}

TEST(Mtl, UnsupportedStatementsWarnOncePerKeywordPerFile) {
    TempDir dir;
    const std::string text =
        "map_Ks before.png\n"  // before the first newmtl: ignored silently
        "newmtl a\nKd 1 0 0\nmap_Ka a.png\nmap_Ks s.png\n"
        "newmtl b\nmap_Ka b.png\nTf 1 1 1\nmap_Kd d.png\n";
    std::vector<std::string> warnings;
    const std::vector<raykit::Material> mats = raykit::parse_mtl(text, "m.mtl", dir.path(), &warnings);
    ASSERT_EQ(mats.size(), 2u);
    ASSERT_EQ(warnings.size(), 3u);
    EXPECT_EQ(warnings[0].rfind("m.mtl:4: ", 0), 0u) << warnings[0];
    EXPECT_NE(warnings[0].find("'map_Ka'"), std::string::npos) << warnings[0];
    EXPECT_EQ(warnings[1].rfind("m.mtl:5: ", 0), 0u) << warnings[1];
    EXPECT_NE(warnings[1].find("'map_Ks'"), std::string::npos) << warnings[1];
    EXPECT_EQ(warnings[2].rfind("m.mtl:8: ", 0), 0u) << warnings[2];
    EXPECT_NE(warnings[2].find("'Tf'"), std::string::npos) << warnings[2];
    // Every supported statement is silent.
    warnings.clear();
    raykit::parse_mtl("newmtl a\nKa 1\nKd 1 1 1\nKs 0\nKe 0\nNs 1\nNi 1\nd 1\nTr 0\nillum 2\nmap_Kd x.png\n", "n.mtl",
                      dir.path(), &warnings);
    EXPECT_TRUE(warnings.empty()) << warnings[0];
    // Through an OBJ the warnings land in Mesh::warnings, naming the MTL file.
    const fs::path mtl = dir.write("m.mtl", text);
    dir.write("s.obj", "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n");
    const Mesh m = raykit::load_obj(dir.path() / "s.obj");
    ASSERT_EQ(m.warnings.size(), 3u);
    EXPECT_EQ(m.warnings[0].rfind(mtl.string() + ":4: ", 0), 0u) << m.warnings[0];
}

TEST(ObjMaterials, LibrariesCanComeFromMemory) {
    raykit::ObjOptions options;
    std::vector<fs::path> asked;
    options.read_material_library = [&](const fs::path& p) -> std::optional<std::string> {
        asked.push_back(p);
        if (p == fs::path("/nonexistent/raykit") / "mem.mtl") return std::string("newmtl red\nKd 1 0 0\n");
        return std::nullopt;
    };
    const Mesh m = raykit::parse_obj("mtllib mem.mtl gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n",
                                     kFixtureName, "/nonexistent/raykit", options);
    ASSERT_EQ(m.materials.size(), 1u);
    EXPECT_EQ(m.materials[0].kd, vec3(1, 0, 0));
    EXPECT_EQ(m.material_ids, std::vector<std::uint32_t>{0});
    ASSERT_EQ(m.warnings.size(), 1u);
    EXPECT_NE(m.warnings[0].find("gone.mtl"), std::string::npos) << m.warnings[0];
    EXPECT_FALSE(asked.empty());
}

TEST(ObjParse, FilesWithoutTrianglesWarnAndNameAForeignExtension) {
    TempDir dir;
    {
        const Mesh m = parse("v 0 0 0\nv 1 0 0\n");
        ASSERT_EQ(m.warnings.size(), 1u);
        EXPECT_EQ(m.warnings[0].rfind("fixture.obj: no triangles", 0), 0u) << m.warnings[0];
        EXPECT_EQ(m.warnings[0].find("is it an OBJ"), std::string::npos) << m.warnings[0];
    }
    {
        // An SMD given as the scene parses to nothing (its keywords are not OBJ's).
        const fs::path smd = dir.write("walk.smd",
                                       "version 1\nnodes\n0 \"root\" -1\nend\nskeleton\ntime 0\n0 0 0 0 0 0 0\nend\n");
        const Mesh m = raykit::load_obj(smd);
        ASSERT_EQ(m.warnings.size(), 1u);
        EXPECT_NE(m.warnings[0].find(smd.string() + ": no triangles"), std::string::npos) << m.warnings[0];
        EXPECT_NE(m.warnings[0].find("'.smd'"), std::string::npos) << m.warnings[0];
    }
    {
        static const char kHeader[] = "\x89PNG\r\n\x1a\n\0\0\0\rIHDR\0\0\0\x01\0\0\0\x01\x08\x02\0\0\0";
        const std::string png(kHeader, sizeof kHeader - 1);  // the literal's NULs included
        const fs::path bin = dir.write("image.PNG", png);
        const Mesh m = raykit::load_obj(bin);
        ASSERT_EQ(m.warnings.size(), 1u);
        EXPECT_NE(m.warnings[0].find("'.png'"), std::string::npos) << m.warnings[0];
    }
    {
        const Mesh m = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        EXPECT_TRUE(m.warnings.empty());
    }
}

}  // namespace
