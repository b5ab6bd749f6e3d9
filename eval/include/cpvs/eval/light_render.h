// Pictures of a scene lit by a light bundle's lights (seed 000 §6.2): every pixel shaded
// with the lights its screen tile's list holds, each light's CPVS visibility, its cone
// and its fall-off. How a person looks at a night of street lamps.
#pragma once

#include <vector>

#include "cpvs/eval/camera.h"
#include "cpvs/eval/image.h"
#include "cpvs/query/bundle_query.h"
#include "cpvs/query/light_tiles.h"

namespace cpvs {

/// Light i's radiance at a surface point, linear RGB: its visibility (PCF width `pcf`; for
/// a VPL its area light's soft visibility, BundleQuery::softVisibility) times N.L, its
/// colour and intensity, a spot light's cone (smooth from 3/4 of its half-angle to all of
/// it), a VPL's cosine about its emitter's normal, and a fall-off that reaches 0 at its
/// reach.
Rgb lightRadiance(const BundleQuery& query, size_t light, const Vec3& p, const Vec3& n, int pcf);
/// The same with the visibility given (a GPU's lookup: lit texels / pcf²).
Rgb lightRadiance(const BundleQuery& query, size_t light, const Vec3& p, const Vec3& n, float visibility);

/// The lights' sum per pixel over each tile's list (cullLights of the hits), in light
/// order; a faint ambient term and albedo as the sun pictures; sky where nothing is hit.
Image shadeLightTiles(const CameraHits& hits, const BundleQuery& query, const LightTiles& tiles, int pcf);
/// The same with each lookup's visibility given, in the order tileLookups lists them (a
/// VPL's: its area light's soft visibility).
Image shadeLightTiles(const CameraHits& hits, const BundleQuery& query, const LightTiles& tiles,
                      const std::vector<float>& visibility);
/// The lookups shadeLightTiles makes: for every pixel that sees the scene, row by row,
/// each light of its tile's list: the light, the point and its normal.
void tileLookups(const CameraHits& hits, const LightTiles& tiles, std::vector<uint32_t>& lights,
                 std::vector<Vec3>& points, std::vector<Vec3>& normals);
/// The same with every light at every pixel, no culling: the reference the culled
/// picture must equal bit for bit.
Image shadeAllLights(const CameraHits& hits, const BundleQuery& query, int pcf);
/// The hits' points and whether each pixel has one, as cullLights takes them.
void hitPoints(const CameraHits& hits, std::vector<Vec3>& points, std::vector<uint8_t>& hit);

}  // namespace cpvs
