// raykit/render/material.hpp — the render-side material table: MTL materials of a Mesh turned
// into what the shaders read, with their diffuse textures loaded once per file.
//
// Interface
// ---------
//   TextureCache cache;                                   // optional; shares textures between tables
//   MaterialTable mt = make_material_table(mesh, &cache);
//   const RenderMaterial& m = mt.for_triangle(mesh, tri);  // kNoMaterial -> mt.default_material()
//   for (auto& w : mt.warnings) ...                        // e.g. missing texture files
//
// One RenderMaterial per Mesh material, in the same order, plus a default one (the MTL defaults:
// Kd 0.8, no specular, opaque) at the end for triangles without a material. Textures are
// shared: every material naming the same map_Kd path points to the same Texture, loaded once
// (per MaterialTable, and per TextureCache when one is passed); textures of materials that no
// triangle uses are not loaded. A texture that cannot be loaded
// becomes the magenta/black placeholder and one warning per table (see texture.hpp).
//
// MTL interpretation (what the shaders in shade.hpp do with it)
// -------------------------------------------------------------
//   diffuse      Kd, times the map_Kd colour when there is one (decoded from sRGB)
//   specular     Ks with Blinn-Phong exponent Ns (highlights from lights)
//   emission     Ke, added as is
//   reflection   illum 3, 5, 7: mirror reflection weighted by Ks; for 5 and 7 by the Schlick
//                Fresnel term with Ks as normal-incidence reflectance
//   transparency 1 - d when d < 1; otherwise 1 for illum 4, 6, 7 (glass), else 0. The
//                transparent part is split between refraction (index Ni) and reflection by the
//                exact dielectric Fresnel equations
//   cut-outs     map_Kd with alpha: where the filtered alpha is < 0.5 the surface is absent
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "raykit/render/texture.hpp"
#include "raykit/scene/mesh.hpp"
#include "raykit/util/parallel.hpp"

namespace raykit {

struct RenderMaterial {
    std::string name;
    vec3 kd{0.8f};
    vec3 ks{0.0f};
    vec3 ke{0.0f};
    float ns = 0.0f;
    float ni = 1.0f;
    float d = 1.0f;
    int illum = 2;
    const Texture* map_kd = nullptr;  ///< diffuse map (owned by the table / cache), or null

    vec3 mirror{0.0f};         ///< mirror reflectance (Ks for illum 3, 5, 7, else 0)
    bool fresnel_mirror = false;  ///< illum 5, 7: mirror weighted by Schlick's term with F0 = Ks
    float transparency = 0.0f;    ///< fraction of light passing the surface (refraction + its Fresnel reflection)
    bool alpha_tested = false;    ///< map_kd has texels with alpha < 0.5

    /// Derives mirror, fresnel_mirror, transparency and alpha_tested from the MTL fields.
    void update_derived() noexcept {
        const bool reflects = illum == 3 || illum == 5 || illum == 7;
        mirror = reflects ? ks : vec3(0.0f);
        fresnel_mirror = illum == 5 || illum == 7;
        const float dd = std::clamp(std::isfinite(d) ? d : 1.0f, 0.0f, 1.0f);
        transparency = dd < 1.0f ? 1.0f - dd : (illum == 4 || illum == 6 || illum == 7 ? 1.0f : 0.0f);
        if (!(ni > 0.0f) || !std::isfinite(ni)) ni = 1.0f;
        alpha_tested = map_kd != nullptr && map_kd->has_cutout;
    }
};

/// Thread-safe cache of loaded textures keyed by (file path, sRGB flag). Entries live as long as
/// the cache or any MaterialTable that uses them.
class TextureCache {
  public:
    struct Entry {
        std::shared_ptr<const Texture> texture;
        std::string warning;  ///< "" when the file loaded
    };

    /// The texture for `path`, loading it on first use.
    Entry get(const std::string& path, bool srgb = true) {
        {
            std::lock_guard lock(mutex_);
            if (auto it = entries_.find({path, srgb}); it != entries_.end()) return it->second;
        }
        std::vector<std::string> w;
        Entry e{std::make_shared<const Texture>(load_texture(path, srgb, &w)), w.empty() ? std::string() : w.front()};
        std::lock_guard lock(mutex_);
        return entries_.try_emplace({path, srgb}, std::move(e)).first->second;
    }
    std::size_t size() const {
        std::lock_guard lock(mutex_);
        return entries_.size();
    }
    void clear() {
        std::lock_guard lock(mutex_);
        entries_.clear();
    }

  private:
    mutable std::mutex mutex_;
    std::map<std::pair<std::string, bool>, Entry> entries_;
};

struct MaterialTable {
    std::vector<RenderMaterial> materials;  ///< Mesh::materials order, then the default material
    std::vector<std::shared_ptr<const Texture>> textures;  ///< the distinct textures in use
    std::vector<std::string> warnings;      ///< one per texture that could not be loaded

    MaterialTable() { materials.emplace_back().update_derived(); }

    const RenderMaterial& default_material() const noexcept { return materials.back(); }
    /// Material `id` (an index into Mesh::materials); kNoMaterial or any out-of-range id gives
    /// the default material.
    const RenderMaterial& get(std::uint32_t id) const noexcept {
        return id < materials.size() - 1 ? materials[id] : materials.back();
    }
    /// The material of triangle `tri` of `mesh` (default when the mesh has no material ids).
    const RenderMaterial& for_triangle(const Mesh& mesh, std::size_t tri) const noexcept {
        return tri < mesh.material_ids.size() ? get(mesh.material_ids[tri]) : materials.back();
    }
    /// True when some material is alpha-tested (shaders then test alpha during traversal).
    bool any_alpha_tested() const noexcept {
        for (const RenderMaterial& m : materials)
            if (m.alpha_tested) return true;
        return false;
    }
    std::size_t texture_bytes() const noexcept {
        std::size_t n = 0;
        for (const auto& t : textures) n += t->memory_bytes();
        return n;
    }
};

/// Builds the table for `mesh`. Textures come from `cache` when given (and are added to it),
/// otherwise each distinct path is loaded once for this table. Only materials that some
/// triangle uses get their map_Kd loaded (MTL libraries often define many more; an unused
/// material keeps map_kd = nullptr). Distinct files are loaded on up to `threads` threads
/// (0 = all hardware threads). Never throws for missing textures (see the warnings); throws
/// only on allocation failure.
inline MaterialTable make_material_table(const Mesh& mesh, TextureCache* cache = nullptr, unsigned threads = 0) {
    MaterialTable t;
    t.materials.clear();
    t.materials.reserve(mesh.materials.size() + 1);
    TextureCache local;
    TextureCache& c = cache ? *cache : local;
    std::vector<char> used(mesh.materials.size(), 0);
    for (std::uint32_t id : mesh.material_ids)
        if (id < used.size()) used[id] = 1;
    // the distinct texture files of the used materials, in material order, loaded in parallel
    std::vector<std::string> paths;
    std::map<std::string, std::size_t> slot;
    for (std::size_t mi = 0; mi < mesh.materials.size(); ++mi)
        if (used[mi] && !mesh.materials[mi].map_kd.empty() && slot.emplace(mesh.materials[mi].map_kd, paths.size()).second)
            paths.push_back(mesh.materials[mi].map_kd);
    std::vector<TextureCache::Entry> entries(paths.size());
    parallel_chunks(paths.size(), paths.size(), threads, [&](std::size_t, std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) entries[i] = c.get(paths[i], true);
    });
    for (TextureCache::Entry& e : entries) {
        if (!e.warning.empty()) t.warnings.push_back(e.warning);
        t.textures.push_back(e.texture);
    }
    for (std::size_t mi = 0; mi < mesh.materials.size(); ++mi) {
        const Material& m = mesh.materials[mi];
        RenderMaterial r;
        r.name = m.name;
        r.kd = m.kd;
        r.ks = m.ks;
        r.ke = m.ke;
        r.ns = m.ns;
        r.ni = m.ni;
        r.d = m.d;
        r.illum = m.illum;
        if (auto it = slot.find(m.map_kd); used[mi] && it != slot.end()) r.map_kd = entries[it->second].texture.get();
        r.update_derived();
        t.materials.push_back(std::move(r));
    }
    t.materials.emplace_back();
    t.materials.back().name = "(default)";
    t.materials.back().update_derived();
    return t;
}

}  // namespace raykit
