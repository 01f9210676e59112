// OBJ + MTL through parse_obj and parse_mtl (io/obj.hpp). The input is an OBJ text,
// optionally followed by a line `%%MTL` and an MTL text: every `mtllib` name resolves
// to that MTL through ObjOptions::read_material_library (names starting with "missing"
// resolve to nothing), so the file system is never read for libraries. Bad input must
// be a ParseError "NAME:LINE: ..." naming the OBJ or the MTL. A Mesh that parses must
// have every triangle index < vertex count, material ids valid or kNoMaterial, one
// material id per triangle, normals/texcoords empty or one per vertex, finite
// positions, normals, texcoords and material numbers, and `o`/`g` ranges inside the
// triangle list in order. A lone MTL (the part after the marker) is checked the same.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "raykit/io/obj.hpp"

namespace {

void check(bool ok) {
    if (!ok) __builtin_trap();
}

bool finite3(const raykit::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

void check_material(const raykit::Material& m) {
    check(finite3(m.ka) && finite3(m.kd) && finite3(m.ks) && finite3(m.ke));
    check(std::isfinite(m.ns) && std::isfinite(m.ni) && std::isfinite(m.d));
}

void check_error(const raykit::ParseError& e) {
    check(!e.file().empty());  // fuzz.obj, or base_dir / NAME of the carried MTL
    // what() is a C string: a NUL inside a file name ends it early.
    // "FILE:LINE: ", or "FILE: " for an error not tied to a line (line 0)
    const std::string prefix = e.file() + (e.line() ? ":" + std::to_string(e.line()) : std::string()) + ": ";
    check(std::string(e.what()).rfind(prefix.substr(0, prefix.find('\0')), 0) == 0);
}

void check_mesh(const raykit::Mesh& m) {
    const std::size_t nv = m.positions.size(), nt = m.triangles.size();
    check(m.material_ids.size() == nt);
    check(m.normals.empty() || m.normals.size() == nv);
    check(m.texcoords.empty() || m.texcoords.size() == nv);
    for (const raykit::Triangle& t : m.triangles) {
        for (std::uint32_t i : t.v) check(i < nv);
    }
    for (std::uint32_t id : m.material_ids) check(id == raykit::kNoMaterial || id < m.materials.size());
    for (const raykit::vec3& p : m.positions) check(finite3(p));
    for (const raykit::vec3& n : m.normals) check(finite3(n));
    for (const raykit::vec2& t : m.texcoords) check(std::isfinite(t.x) && std::isfinite(t.y));
    for (const raykit::Material& mat : m.materials) check_material(mat);
    for (const auto* list : {&m.objects, &m.groups}) {
        std::uint64_t next = 0;
        for (const raykit::Group& g : *list) {
            check(g.first_triangle >= next);
            next = std::uint64_t{g.first_triangle} + g.triangle_count;
            check(next <= nt);
        }
    }
    if (nt == 0) check(!m.warnings.empty());  // a file without triangles is reported
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view input(reinterpret_cast<const char*>(data), size);
    constexpr std::string_view kMarker = "\n%%MTL\n";
    const std::size_t cut = input.find(kMarker);
    const std::string_view obj = input.substr(0, cut);
    const std::optional<std::string> mtl =
        cut == std::string_view::npos ? std::nullopt : std::optional<std::string>(input.substr(cut + kMarker.size()));

    raykit::ObjOptions options;
    options.read_material_library = [&](const std::filesystem::path& p) -> std::optional<std::string> {
        if (p.filename().string().rfind("missing", 0) == 0) return std::nullopt;
        return mtl;
    };
    try {
        check_mesh(raykit::parse_obj(obj, "fuzz.obj", "/nonexistent-raykit-fuzz", options));
    } catch (const raykit::ParseError& e) {
        check_error(e);
    }
    if (mtl) {
        try {
            std::vector<std::string> warnings;
            for (const raykit::Material& m : raykit::parse_mtl(*mtl, "fuzz.mtl", "/nonexistent-raykit-fuzz", &warnings)) {
                check_material(m);
            }
            for (const std::string& w : warnings) check(w.rfind("fuzz.mtl:", 0) == 0);
        } catch (const raykit::ParseError& e) {
            check(e.file() == "fuzz.mtl");
            check_error(e);
        }
    }
    return 0;
}
