// raykit/io/obj_write.hpp — write a mesh as OBJ (positions, normals, uvs, faces).
#pragma once

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include "raykit/scene/mesh.hpp"

namespace raykit {

/// Writes `mesh` to `file` with 9 significant digits per float (enough to
/// round-trip every float exactly). Throws std::runtime_error on I/O failure.
inline void save_obj(const Mesh& mesh, const std::filesystem::path& file) {
    std::ofstream out(file, std::ios::binary);
    if (!out) throw std::runtime_error("cannot write " + file.string());
    char buf[128];
    out << "# written by raykit\n";
    for (const vec3& p : mesh.positions) {
        std::snprintf(buf, sizeof buf, "v %.9g %.9g %.9g\n", p.x, p.y, p.z);
        out << buf;
    }
    for (const vec2& t : mesh.texcoords) {
        std::snprintf(buf, sizeof buf, "vt %.9g %.9g\n", t.x, t.y);
        out << buf;
    }
    for (const vec3& n : mesh.normals) {
        std::snprintf(buf, sizeof buf, "vn %.9g %.9g %.9g\n", n.x, n.y, n.z);
        out << buf;
    }
    const bool nt = !mesh.texcoords.empty(), nn = !mesh.normals.empty();
    for (const Triangle& t : mesh.triangles) {
        out << 'f';
        for (int c = 0; c < 3; ++c) {
            const unsigned i = t.v[c] + 1;
            if (nt && nn) std::snprintf(buf, sizeof buf, " %u/%u/%u", i, i, i);
            else if (nt) std::snprintf(buf, sizeof buf, " %u/%u", i, i);
            else if (nn) std::snprintf(buf, sizeof buf, " %u//%u", i, i);
            else std::snprintf(buf, sizeof buf, " %u", i);
            out << buf;
        }
        out << '\n';
    }
    if (!out) throw std::runtime_error("error writing " + file.string());
}

}  // namespace raykit
