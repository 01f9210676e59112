// Tests for raykit/io/rays.hpp: the RAYS format `raykit trace` reads, its one
// number rule (shared with OBJ and MTL), and what it refuses.
#include "raykit/io/rays.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <sys/stat.h>

#include "raykit/io/obj.hpp"
#include "test_text.hpp"

namespace fs = std::filesystem;
using raykit::ParseError;
using raykit::Ray;
using raykit::vec3;

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

std::vector<Ray> parse(const std::string& text) { return raykit::parse_rays(text, "r.txt"); }

/// Expects a ParseError for `file` at `line` whose message contains `fragment`.
template <class F>
void expect_error(F&& f, const std::string& file, std::size_t line, const std::string& fragment) {
    std::optional<ParseError> e;
    try {
        f();
    } catch (const ParseError& x) {
        e = x;
    }
    ASSERT_TRUE(e.has_value()) << "no ParseError thrown";
    EXPECT_EQ(e->file(), file);
    EXPECT_EQ(e->line(), line) << e->what();
    const std::string what = e->what();
    // an error tied to no line reads "FILE: ..." (ParseError), others "FILE:LINE: ..."
    EXPECT_EQ(what.rfind(line == 0 ? file + ": " : file + ":" + std::to_string(line) + ": ", 0), 0u) << what;
    EXPECT_NE(what.find(fragment), std::string::npos) << "'" << fragment << "' not in: " << what;
}

void expect_rays_error(const std::string& text, std::size_t line, const std::string& fragment) {
    SCOPED_TRACE(text);
    expect_error([&] { parse(text); }, "r.txt", line, fragment);
}

TEST(Rays, FieldsCommentsBlankLinesAndLineEndings) {
    const std::vector<Ray> rays = parse(
        "\xEF\xBB\xBF# header\n"
        "0 0 -5 0 0 1 0 inf\n"
        "\n"
        "   \t\n"
        "  # indented comment\n"
        "1.5\t-2 +3 .5 -.5 5. 1e-3 1E+2\r\n"
        "1 2 3 4 5 6 7 8");  // no final newline
    ASSERT_EQ(rays.size(), 3u);
    EXPECT_EQ(rays[0].org, vec3(0, 0, -5));
    EXPECT_EQ(rays[0].dir, vec3(0, 0, 1));
    EXPECT_EQ(rays[0].tmin, 0.0f);
    EXPECT_EQ(rays[0].tmax, kInf);
    EXPECT_EQ(rays[1].org, vec3(1.5f, -2.0f, 3.0f));
    EXPECT_EQ(rays[1].dir, vec3(0.5f, -0.5f, 5.0f));
    EXPECT_EQ(rays[1].tmin, 1e-3f);
    EXPECT_EQ(rays[1].tmax, 100.0f);
    EXPECT_EQ(rays[2].org, vec3(1, 2, 3));
    EXPECT_EQ(rays[2].tmax, 8.0f);
    EXPECT_TRUE(parse("").empty());
    EXPECT_TRUE(parse("# only\n\n").empty());
}

TEST(Rays, ByteOrderMarksAndUtf16AsInObj) {
    // io/lexer.hpp's one rule for every reader: a UTF-8 BOM is skipped, UTF-16 with a BOM converted
    const std::string text = "# caf\xC3\xA9 \xF0\x9F\x98\x80\n0 0 -5 0 0 1 0 inf\r\n1.5 -2 3 .5 -.5 5 1e-3 100\n";
    const std::vector<Ray> plain = parse(text);
    ASSERT_EQ(plain.size(), 2u);
    auto expect_plain = [&](const std::vector<Ray>& rays, const char* what) {
        ASSERT_EQ(rays.size(), plain.size()) << what;
        for (std::size_t i = 0; i < rays.size(); ++i) {
            EXPECT_EQ(rays[i].org, plain[i].org) << what << " ray " << i;
            EXPECT_EQ(rays[i].dir, plain[i].dir) << what << " ray " << i;
            EXPECT_EQ(rays[i].tmin, plain[i].tmin) << what << " ray " << i;
            EXPECT_EQ(rays[i].tmax, plain[i].tmax) << what << " ray " << i;
        }
    };
    expect_plain(parse("\xEF\xBB\xBF" + text), "UTF-8 BOM");
    for (bool big : {true, false}) {
        const char* what = big ? "UTF-16BE" : "UTF-16LE";
        expect_plain(parse(raykit::test::utf16_with_bom(text, big)), what);
        SCOPED_TRACE(what);  // errors name the text's line
        expect_error([&] { parse(raykit::test::utf16_with_bom(text + "0 0 -5 0 zero 1 0 inf\n", big)); }, "r.txt", 4,
                     "malformed number 'zero' in 'dy'");
    }
    expect_error([] { parse(std::string("\xFE\xFF\x00", 3)); }, "r.txt", 0, "UTF-16");
}

TEST(Rays, OnlyTmaxMayBeInfinite) {
    for (const char* inf : {"inf", "+inf", "INF", "Infinity", "+infinity"}) {
        const std::vector<Ray> r = parse(std::string("0 0 0 0 0 1 0 ") + inf + "\n");
        ASSERT_EQ(r.size(), 1u) << inf;
        EXPECT_EQ(r[0].tmax, kInf) << inf;
    }
    expect_rays_error("0 0 0 0 0 1 0 -inf\n", 1, "non-finite number '-inf' in 'tmax'");
    expect_rays_error("0 0 0 0 0 1 0 nan\n", 1, "non-finite number 'nan' in 'tmax'");
    expect_rays_error("0 0 0 0 0 1 0 1\ninf 0 0 0 0 1 0 1\n", 2, "in 'ox'");
    expect_rays_error("0 0 0 0 0 1 inf inf\n", 1, "in 'tmin'");
    expect_rays_error("0 0 nan 0 0 1 0 inf\n", 1, "non-finite number 'nan' in 'oz'");
    expect_rays_error("0 0 0 0 0 infinity 0 1\n", 1, "in 'dz'");
}

TEST(Rays, OneNumberRuleWithObj) {
    // Too small for a float: 0 (sign kept) or a subnormal, as in an OBJ file.
    const std::vector<Ray> r = parse("1e-46 -1e-46 1e-40 0 0 1 1e-50 1e-45\n");
    ASSERT_EQ(r.size(), 1u);
    EXPECT_EQ(r[0].org.x, 0.0f);
    EXPECT_TRUE(std::signbit(r[0].org.y));
    EXPECT_EQ(r[0].org.z, 1e-40f);
    EXPECT_EQ(r[0].tmin, 0.0f);
    EXPECT_EQ(r[0].tmax, 1e-45f);
    // Too large: an error naming the value, even for tmax (inf must be written).
    expect_rays_error("1e39 0 0 0 0 1 0 1\n", 1, "number '1e39' overflows a float in 'ox'");
    expect_rays_error("0 0 0 0 0 1 0 1e39\n", 1, "number '1e39' overflows a float in 'tmax'");
    expect_rays_error("0 0 0 0 0 1 0 -1e400\n", 1, "overflows a float");
    // The OBJ loader agrees on every one of these.
    const raykit::Mesh m = raykit::parse_obj("v 1e-46 -1e-46 1e-40\nv 0 0 1\nv 0 1 0\nf 1 2 3\n", "m.obj", {});
    EXPECT_EQ(m.positions[0].x, r[0].org.x);
    EXPECT_EQ(m.positions[0].z, r[0].org.z);
    expect_error([] { raykit::parse_obj("v 1e39 0 0\n", "m.obj", {}); }, "m.obj", 1, "number '1e39' overflows");
}

TEST(Rays, MalformedLinesNameFileAndLine) {
    const std::string good = "0 0 -5 0 0 1 0 inf\n";
    expect_rays_error(good + "0 0 -5 0 0 1 0\n", 2, "expected 8 fields");
    expect_rays_error(good + "0 0 -5 0 0 1 0 inf 7\n", 2, "got 9");
    expect_rays_error(good + good + "0 0 -5 0 zero 1 0 inf\n", 3, "malformed number 'zero' in 'dy'");
    expect_rays_error("0 0 -5 0 0 1 0 inf # trailing\n", 1, "expected 8 fields");
    expect_rays_error("0x1p3 0 0 0 0 1 0 1\n", 1, "malformed number");
    expect_rays_error("0,5 0 0 0 0 1 0 1\n", 1, "malformed number");
}

TEST(Rays, AbsurdlyLongLineIsRefused) {
    const std::string big(raykit::kMaxLineBytes + 1, ' ');
    expect_rays_error("0 0 0 0 0 1 0 1\n" + big + "\n", 2, "line longer than");
}

TEST(Rays, ReadRaysRefusesWhatIsNotARegularFile) {
    std::random_device rd;
    const fs::path dir = fs::temp_directory_path() / ("raykit_test_rays_" + std::to_string(rd()));
    fs::create_directories(dir);
    // `trace` given a directory used to write an empty HITS file and exit 0.
    expect_error([&] { raykit::read_rays(dir); }, dir.string(), 0, "is a directory");
    expect_error([&] { raykit::read_rays(dir / "missing.txt"); }, (dir / "missing.txt").string(), 0, "cannot open");
    if (fs::exists("/dev/zero")) {
        expect_error([] { raykit::read_rays("/dev/zero"); }, "/dev/zero", 0, "not a regular file");
    }
    const fs::path fifo = dir / "pipe.txt";
    if (::mkfifo(fifo.c_str(), 0600) == 0) {
        expect_error([&] { raykit::read_rays(fifo); }, fifo.string(), 0, "not a regular file");
    }
    const fs::path file = dir / "rays.txt";
    std::ofstream(file) << "1 2 3 0 0 1 0 inf\n";
    const std::vector<Ray> r = raykit::read_rays(file);
    ASSERT_EQ(r.size(), 1u);
    EXPECT_EQ(r[0].org, vec3(1, 2, 3));
    std::error_code ec;
    fs::remove_all(dir, ec);
}

}  // namespace

// Issue 12, defect 8: rays the triangle tests could answer wrongly (math/limits.hpp) are refused
// where they are read, naming the line, instead of tracing to a wrong hit or t = inf.
TEST(Rays, RaysOutsideTheRangeRuleAreRefusedNamingTheLine) {
    const std::string ok = "0 0 -5 0 0 1 0 inf\n";
    EXPECT_EQ(raykit::parse_rays(ok, "r.txt").size(), 1u);
    EXPECT_EQ(raykit::parse_rays("4294967296 0 0 -1 0 0 0 inf\n", "r.txt").size(), 1u);  // 2^32: inside
    expect_rays_error(ok + "1e14 0 0 -1 0 0 0 inf\n", 2, "origin x = 1e+14");
    expect_rays_error(ok + ok + "0 0 0 0 0 0 0 inf\n", 3, "direction");
    expect_rays_error("0 0 0 0 0 1e-6 0 inf\n", 1, "direction");
    expect_rays_error("0 0 0 0 1e30 0 0 inf\n", 1, "direction");
}
