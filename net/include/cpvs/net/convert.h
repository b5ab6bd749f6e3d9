// Conversions between the farm's messages and the core's types, with the validation every
// process applies at its boundary.
#pragma once

#include <string>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/light/frame.h"
#include "cpvs/light/grid_spec.h"
#include "cpvs/light/area_light.h"
#include "cpvs/light/light.h"
#include "cpvs/base/vec3.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/error.h"
#include "cpvs/net/farm_model.h"
#include "cpvs/v1/farm.pb.h"

namespace cpvs::net {

namespace pb = ::cpvs::v1;

pb::Vec3 toProto(const Vec3& v);
Vec3 fromProto(const pb::Vec3& v);

/// A light of the contract and back (resolution "" for a planned one); the core's checks
/// (checkLight) are the caller's. InputError for a resolution that does not parse.
pb::Light toProto(const Light& l);
Light fromProto(const pb::Light& l);

/// InputError for a hash other than XXH3 (the farm has no other).
pb::BakeOptions toProto(const BakeOptions& o);
/// Validates enum values and the tile size (log2TileSizeOf; 0 = the default, 4096).
/// Throws InputError naming the field.
BakeOptions fromProto(const pb::BakeOptions& o);

/// Limits of a receiver declaration on the wire.
constexpr int kMaxReceiverBoxes = 4096;

/// Validates a receiver declaration's fields that need no scene: the kind, an odd PCF
/// width in [1, 9] (0 = 9), a volume (an uploaded mesh's hash and/or at most
/// kMaxReceiverBoxes finite boxes with min < max) exactly for RECEIVERS_VOLUME.
/// InputError naming the field.
void checkReceivers(const pb::Receivers& r);

/// A grid of either projection, field for field (the contract's GridSpec is the core's).
pb::GridSpec toProto(const GridSpec& g);
/// InputError for an unknown projection or a resolution out of range; the other fields
/// are checked by the grid made from it (orthoGridOf, perspectiveGridOf), as the file
/// readers check theirs.
GridSpec gridSpecOf(const pb::GridSpec& g);

/// An area light of the contract and back (vpls 0 and resolution "": the defaults).
pb::AreaLight toProto(const AreaLight& a);
/// The spec's area lights, converted and checked for what needs no scene (checkAreaLight
/// of the rectangle, the VPL count and resolution; the scene's bounds are the caller's).
/// InputError naming "area_lights[i]".
std::vector<AreaLight> areaLightsOf(const pb::BakeSpec& spec);

/// Whether the spec asks for a light bundle (lights, area lights or scene_lights) rather
/// than a sun.
bool isLightBundle(const pb::BakeSpec& spec);
/// The spec's own lights (not the scene's), converted and checked for what needs no
/// scene: a known kind, a spot light with a direction, a resolution that parses, no area
/// number (the farm numbers the VPLs of area_lights), at most kMaxLights. InputError
/// naming "lights[i]".
std::vector<Light> lightsOf(const pb::BakeSpec& spec);

/// The light of a spec: a finite non-zero direction or a sun above the horizon.
LightFrame lightOf(const pb::BakeSpec& spec);

/// The JSON form of a spec (a job file) and back; InputError with protobuf's message.
std::string specToJson(const pb::BakeSpec& spec);
pb::BakeSpec specFromJson(const std::string& json, const std::string& source);

}  // namespace cpvs::net
