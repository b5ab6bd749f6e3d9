#include "cpvs/base/error.h"
#include "cpvs/net/convert.h"

#include <google/protobuf/util/json_util.h>
#include <xxhash.h>

#include <cmath>

#include "cpvs/base/file.h"
#include "cpvs/base/parse.h"
#include "cpvs/io/bundle_file.h"

namespace cpvs::net {

pb::Vec3 toProto(const Vec3& v) {
  pb::Vec3 p;
  p.set_x(v.x);
  p.set_y(v.y);
  p.set_z(v.z);
  return p;
}

Vec3 fromProto(const pb::Vec3& v) { return {v.x(), v.y(), v.z()}; }

static_assert(int(LightKind::Spot) == pb::LIGHT_SPOT && int(LightKind::Point) == pb::LIGHT_POINT);

pb::Light toProto(const Light& l) {
  pb::Light p;
  p.set_kind(pb::LightKind(l.kind));
  p.set_name(l.name);
  *p.mutable_position() = toProto(l.position);
  if (l.kind == LightKind::Spot || l.area != 0) *p.mutable_direction() = toProto(l.direction);
  if (l.kind == LightKind::Spot) p.set_cone_deg(l.coneDeg);
  p.set_area(l.area);
  p.set_range(l.range);
  *p.mutable_colour() = toProto(l.colour);
  p.set_intensity(l.intensity);
  p.set_near(l.near);
  if (l.log2Resolution != 0) p.set_resolution(std::to_string(uint64_t(1) << l.log2Resolution));
  for (const std::string& name : l.exclude) p.add_exclude(name);
  return p;
}

Light fromProto(const pb::Light& p) {
  Light l;
  if (p.kind() != pb::LIGHT_SPOT && p.kind() != pb::LIGHT_POINT)
    throw InputError("light kind " + std::to_string(int(p.kind())) + " is unknown");
  l.kind = LightKind(p.kind());
  l.name = p.name();
  l.position = fromProto(p.position());
  if (p.has_direction()) l.direction = fromProto(p.direction());
  if (l.kind == LightKind::Spot) l.coneDeg = p.cone_deg();
  l.range = p.range();
  if (p.has_colour()) l.colour = fromProto(p.colour());
  if (p.has_intensity()) l.intensity = p.intensity();
  l.near = p.near();
  if (!p.resolution().empty()) l.log2Resolution = parseResolution(p.resolution());
  l.exclude.assign(p.exclude().begin(), p.exclude().end());
  l.area = p.area();
  return l;
}

pb::AreaLight toProto(const AreaLight& a) {
  pb::AreaLight p;
  p.set_name(a.name);
  *p.mutable_centre() = toProto(a.centre);
  *p.mutable_edge_u() = toProto(a.edgeU);
  *p.mutable_edge_v() = toProto(a.edgeV);
  p.set_vpls(a.vpls);
  p.set_resolution(std::to_string(uint64_t(1) << a.log2Resolution));
  p.set_seed(a.seed);
  *p.mutable_colour() = toProto(a.colour);
  p.set_intensity(a.intensity);
  p.set_range(a.range);
  return p;
}

std::vector<AreaLight> areaLightsOf(const pb::BakeSpec& spec) {
  if (size_t(spec.area_lights_size()) > kMaxLights) checkLightCount(size_t(spec.area_lights_size()));
  std::vector<AreaLight> out;
  for (int i = 0; i < spec.area_lights_size(); ++i) {
    const pb::AreaLight& p = spec.area_lights(i);
    const std::string what = "area_lights[" + std::to_string(i) + "]";
    AreaLight a;
    a.name = p.name();
    a.centre = fromProto(p.centre());
    a.edgeU = fromProto(p.edge_u());
    a.edgeV = fromProto(p.edge_v());
    if (p.vpls() != 0) a.vpls = p.vpls();
    try {
      if (!p.resolution().empty()) a.log2Resolution = parseResolution(p.resolution());
    } catch (const InputError& e) {
      throw InputError(what + ": " + e.what());
    }
    a.seed = p.seed();
    if (p.has_colour()) a.colour = fromProto(p.colour());
    if (p.has_intensity()) a.intensity = p.intensity();
    a.range = p.range();
    if (a.name.size() > kMaxLightNameBytes - 16) throw InputError(what + ": the name is longer than " + std::to_string(kMaxLightNameBytes - 16) + " bytes");
    checkAreaLight(a, a.centre, a.centre, what);
    out.push_back(std::move(a));
  }
  return out;
}

std::vector<Light> readLightsFile(const std::string& path) {
  const std::vector<uint8_t> bytes = readFile(path);
  pb::LightList list;
  const auto status = google::protobuf::util::JsonStringToMessage(std::string(bytes.begin(), bytes.end()), &list);
  if (!status.ok()) throw InputError(path + ": not a lights file: " + std::string(status.message()));
  try {
    checkLightCount(size_t(list.lights_size()));
    std::vector<Light> lights;
    for (int i = 0; i < list.lights_size(); ++i) {
      if (list.lights(i).kind() == pb::LIGHT_SPOT && !list.lights(i).has_direction())
        throw InputError("light " + std::to_string(i) + ": a spot light needs a direction");
      lights.push_back(fromProto(list.lights(i)));
    }
    return lights;
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  }
}

// The proto's enum values are the core's: conversions are casts.
static_assert(int(ClosedMode::Auto) == pb::CLOSED_AUTO && int(ClosedMode::On) == pb::CLOSED_ON &&
              int(ClosedMode::Off) == pb::CLOSED_OFF);
static_assert(int(ExitMode::Exact) == pb::EXIT_EXACT && int(ExitMode::Approx) == pb::EXIT_APPROX);
static_assert(int(CompressMode::TopDown) == pb::COMPRESS_TOPDOWN && int(CompressMode::BottomUp) == pb::COMPRESS_BOTTOMUP &&
              int(CompressMode::None) == pb::COMPRESS_NONE);
static_assert(int(UndefinedRule::New) == pb::UNDEFINED_NEW && int(UndefinedRule::Old) == pb::UNDEFINED_OLD &&
              int(UndefinedRule::Aligned) == pb::UNDEFINED_ALIGNED);
static_assert(int(Renderer::Embree) == pb::RENDERER_EMBREE && int(Renderer::Raster) == pb::RENDERER_RASTER);
static_assert(pb::Renderer_ARRAYSIZE == int(OptionNames<Renderer>::kNames.size()) &&
              pb::ClosedMode_ARRAYSIZE == int(OptionNames<ClosedMode>::kNames.size()) &&
              pb::ExitMode_ARRAYSIZE == int(OptionNames<ExitMode>::kNames.size()) &&
              pb::CompressMode_ARRAYSIZE == int(OptionNames<CompressMode>::kNames.size()) &&
              pb::UndefinedRule_ARRAYSIZE == int(OptionNames<UndefinedRule>::kNames.size()),
              "every value of an option exists on both sides");

static_assert(int(ReceiverKind::Everywhere) == pb::RECEIVERS_EVERYWHERE && int(ReceiverKind::Surfaces) == pb::RECEIVERS_SURFACES &&
              int(ReceiverKind::SurfacesTwoSided) == pb::RECEIVERS_SURFACES_TWO_SIDED &&
              int(ReceiverKind::Volume) == pb::RECEIVERS_VOLUME && int(ReceiverKind::Cameras) == pb::RECEIVERS_CAMERAS &&
              pb::ReceiverKind_ARRAYSIZE == int(OptionNames<ReceiverKind>::kNames.size()));
static_assert(int(CameraVisibility::Faced) == pb::CAMERA_VISIBILITY_FACED &&
              int(CameraVisibility::Sampled) == pb::CAMERA_VISIBILITY_SAMPLED &&
              pb::CameraVisibility_ARRAYSIZE == int(OptionNames<CameraVisibility>::kNames.size()));

void checkReceivers(const pb::Receivers& r) {
  if (!isOptionValue<ReceiverKind>(r.kind()))
    throw InputError("options.receivers.kind: unknown value " + std::to_string(r.kind()));
  const uint32_t pcf = r.max_pcf();
  if (pcf != 0 && (pcf % 2 == 0 || pcf > uint32_t(kMaxPcfWidthOption)))
    throw InputError("options.receivers.max_pcf " + std::to_string(pcf) + " must be odd and between 1 and 9");
  const bool volume = r.kind() == pb::RECEIVERS_VOLUME, cameras = r.kind() == pb::RECEIVERS_CAMERAS;
  const bool declared = !r.volume_scene_hash().empty() || r.boxes_size() > 0 || r.ground_layer() != 0;
  if (volume && !declared)
    throw InputError("options.receivers: RECEIVERS_VOLUME needs volume_scene_hash, boxes or ground_layer");
  if (!volume && !cameras && declared)
    throw InputError("options.receivers: only RECEIVERS_VOLUME and RECEIVERS_CAMERAS take a volume");
  const bool places = r.camera_regions_size() > 0 || r.camera_points_size() > 0 || r.camera_paths_size() > 0;
  if (cameras != places)
    throw InputError("options.receivers: camera_regions, camera_points or camera_paths are needed for RECEIVERS_CAMERAS, "
                     "and only there");
  if (!isOptionValue<CameraVisibility>(r.camera_visibility()))
    throw InputError("options.receivers.camera_visibility: unknown value " + std::to_string(r.camera_visibility()));
  const bool sampled = r.camera_visibility() == pb::CAMERA_VISIBILITY_SAMPLED;
  if (sampled && !cameras) throw InputError("options.receivers.camera_visibility is for RECEIVERS_CAMERAS only");
  if (!sampled && (r.camera_spacing() != 0 || r.camera_rays() != 0))
    throw InputError("options.receivers: camera_spacing and camera_rays are for CAMERA_VISIBILITY_SAMPLED only");
  if (!(r.camera_spacing() >= 0 && std::isfinite(r.camera_spacing())))
    throw InputError("options.receivers.camera_spacing must be a finite number >= 0");
  if (r.camera_rays() > kMaxCameraRays)
    throw InputError("options.receivers.camera_rays " + std::to_string(r.camera_rays()) + " is above " +
                     std::to_string(kMaxCameraRays));
  size_t pathPoints = 0;
  for (const pb::CameraPath& path : r.camera_paths()) {
    if (path.points_size() == 0) throw InputError("options.receivers.camera_paths: a path has no points");
    pathPoints += size_t(path.points_size());
    for (const pb::Vec3& p : path.points())
      if (!isFinite(fromProto(p))) throw InputError("options.receivers.camera_paths: a point is not finite");
  }
  for (const pb::Vec3& p : r.camera_points())
    if (!isFinite(fromProto(p))) throw InputError("options.receivers.camera_points: a point is not finite");
  if (size_t(r.camera_points_size()) + pathPoints > size_t(kMaxReceiverBoxes))
    throw InputError("options.receivers: " + std::to_string(size_t(r.camera_points_size()) + pathPoints) +
                     " camera points and path points; at most " + std::to_string(kMaxReceiverBoxes));
  if (cameras ? !(r.view_distance() > 0 && std::isfinite(r.view_distance())) : r.view_distance() != 0)
    throw InputError("options.receivers.view_distance must be positive and finite for RECEIVERS_CAMERAS, 0 otherwise");
  if (!(r.ground_layer() >= 0 && std::isfinite(r.ground_layer())))
    throw InputError("options.receivers.ground_layer must be a finite number >= 0");
  if (r.has_ground_slope_deg() && !(r.ground_slope_deg() >= 0 && r.ground_slope_deg() < 90))
    throw InputError("options.receivers.ground_slope_deg must be at least 0 and below 90");
  if (!(r.ground_layer_from() >= 0 && (r.ground_layer_from() < r.ground_layer() || r.ground_layer_from() == 0)))
    throw InputError("options.receivers.ground_layer_from must be at least 0 and below ground_layer");
  if (r.has_ground_slope_deg() && r.ground_layer() == 0)
    throw InputError("options.receivers.ground_slope_deg needs a ground_layer");
  if (r.camera_regions_size() > kMaxReceiverBoxes)
    throw InputError("options.receivers: " + std::to_string(r.camera_regions_size()) + " camera regions; at most " +
                     std::to_string(kMaxReceiverBoxes));
  if (!r.volume_scene_hash().empty()) parseHashHex(r.volume_scene_hash(), "options.receivers.volume_scene_hash");
  if (r.boxes_size() > kMaxReceiverBoxes)
    throw InputError("options.receivers: " + std::to_string(r.boxes_size()) + " boxes; at most " +
                     std::to_string(kMaxReceiverBoxes));
  for (const auto* list : {&r.boxes(), &r.camera_regions()})
    for (const pb::ReceiverBox& b : *list) {
      const Vec3 lo = fromProto(b.min()), hi = fromProto(b.max());
      const bool finite = std::isfinite(lo.x) && std::isfinite(lo.y) && std::isfinite(lo.z) && std::isfinite(hi.x) &&
                          std::isfinite(hi.y) && std::isfinite(hi.z);
      if (!finite || !(lo.x < hi.x && lo.y < hi.y && lo.z < hi.z))
        throw InputError(std::string("options.receivers.") + (list == &r.boxes() ? "boxes" : "camera_regions") +
                         ": a box is not finite with min < max");
    }
}

pb::BakeOptions toProto(const BakeOptions& o) {
  // The farm hashes with XXH3 only: the weak hash is a hook for tests of one process.
  if (o.hash != HashKind::Xxh3)
    throw InputError(std::string("options.hash ") + optionName(o.hash) + " is not available on the farm");
  pb::BakeOptions p;
  p.set_closed(pb::ClosedMode(int(o.closed)));
  p.set_exit(pb::ExitMode(int(o.exit)));
  p.set_no_cull(!o.cull);
  p.set_compress(pb::CompressMode(int(o.compress)));
  p.set_undefined_rule(pb::UndefinedRule(int(o.undefinedRule)));
  p.set_tile_size(1u << o.log2TileSize);
  p.set_renderer(pb::Renderer(int(o.renderer)));
  if (o.receivers != ReceiverKind::Everywhere) {
    p.mutable_receivers()->set_kind(pb::ReceiverKind(int(o.receivers)));
    p.mutable_receivers()->set_max_pcf(o.receiverPcf);
  }
  return p;
}

BakeOptions fromProto(const pb::BakeOptions& p) {
  auto check = [](bool known, const char* field, int value) {
    if (!known) throw InputError(std::string("options.") + field + ": unknown value " + std::to_string(value));
  };
  check(isOptionValue<ClosedMode>(p.closed()), "closed", p.closed());
  check(isOptionValue<ExitMode>(p.exit()), "exit", p.exit());
  check(isOptionValue<CompressMode>(p.compress()), "compress", p.compress());
  check(isOptionValue<UndefinedRule>(p.undefined_rule()), "undefined_rule", p.undefined_rule());
  check(isOptionValue<Renderer>(p.renderer()), "renderer", p.renderer());
  BakeOptions o;
  o.closed = ClosedMode(p.closed());
  o.exit = ExitMode(p.exit());
  o.cull = !p.no_cull();
  o.compress = CompressMode(p.compress());
  o.undefinedRule = p.has_undefined_rule() ? UndefinedRule(p.undefined_rule()) : UndefinedRule::New;  // absent: an older client's
  o.renderer = p.has_renderer() ? Renderer(p.renderer()) : BakeOptions{}.renderer;
  o.log2TileSize = p.tile_size() == 0 ? kDefaultLog2TileSize : log2TileSizeOf(p.tile_size(), "options.tile_size");
  if (p.has_receivers()) {
    checkReceivers(p.receivers());
    o.receivers = ReceiverKind(p.receivers().kind());
    if (o.receivers != ReceiverKind::Everywhere && p.receivers().max_pcf() != 0) o.receiverPcf = uint8_t(p.receivers().max_pcf());
  }
  return o;
}

pb::GridSpec toProto(const GridSpec& g) {
  pb::GridSpec p;
  p.set_projection(g.projection == Projection::Perspective ? pb::PROJECTION_PERSPECTIVE : pb::PROJECTION_ORTHOGRAPHIC);
  *p.mutable_light_dir() = toProto(g.frame.dir);
  *p.mutable_frame_u() = toProto(g.frame.u);
  *p.mutable_frame_v() = toProto(g.frame.v);
  p.set_log2_resolution(uint32_t(g.log2Resolution));
  if (g.projection == Projection::Orthographic) {
    *p.mutable_origin() = toProto(g.origin);
    p.set_u0(g.u0);
    p.set_v0(g.v0);
    p.set_d0(g.d0);
    p.set_extent(g.extent);
    p.set_depth_extent(g.depthExtent);
    p.set_depth_slices(g.depthSlices);
  } else {
    *p.mutable_position() = toProto(g.position);
    p.set_tan_half_fov(g.tanHalfFov);
    p.set_near(g.near);
    p.set_far(g.far);
    p.set_tan_cone(g.tanCone);
  }
  return p;
}

GridSpec gridSpecOf(const pb::GridSpec& p) {
  GridSpec g;
  switch (p.projection()) {
    case pb::PROJECTION_ORTHOGRAPHIC: g.projection = Projection::Orthographic; break;
    case pb::PROJECTION_PERSPECTIVE: g.projection = Projection::Perspective; break;
    default: throw InputError("grid.projection " + std::to_string(int(p.projection())) + " is not a projection");
  }
  if (p.log2_resolution() > uint32_t(kMaxLog2Resolution))
    throw InputError("grid.log2_resolution " + std::to_string(p.log2_resolution()) + " is out of range");
  g.frame = {fromProto(p.light_dir()), fromProto(p.frame_u()), fromProto(p.frame_v())};
  g.log2Resolution = int(p.log2_resolution());
  g.origin = fromProto(p.origin());
  g.u0 = p.u0(), g.v0 = p.v0(), g.d0 = p.d0();
  g.extent = p.extent(), g.depthExtent = p.depth_extent();
  g.depthSlices = p.depth_slices();
  g.position = fromProto(p.position());
  g.tanHalfFov = p.tan_half_fov(), g.near = p.near(), g.far = p.far(), g.tanCone = p.tan_cone();
  return g;
}

bool isLightBundle(const pb::BakeSpec& spec) {
  return spec.lights_size() > 0 || spec.area_lights_size() > 0 || spec.scene_lights();
}

std::vector<Light> lightsOf(const pb::BakeSpec& spec) {
  // Before converting any: 100,000 lights are refused without 100,000 conversions.
  if (size_t(spec.lights_size()) > kMaxLights) checkLightCount(size_t(spec.lights_size()));
  std::vector<Light> lights;
  for (int i = 0; i < spec.lights_size(); ++i) {
    try {
      if (spec.lights(i).kind() == pb::LIGHT_SPOT && !spec.lights(i).has_direction())
        throw InputError("a spot light needs a direction");
      if (spec.lights(i).area() != 0)
        throw InputError("an area number is the farm's to give the VPLs of area_lights; submit the area light there");
      lights.push_back(fromProto(spec.lights(i)));
    } catch (const InputError& e) {
      throw InputError("lights[" + std::to_string(i) + "]: " + e.what());
    }
  }
  return lights;
}

LightFrame lightOf(const pb::BakeSpec& spec) {
  switch (spec.sun_case()) {
    case pb::BakeSpec::kSunDirection: return LightFrame::fromDirection(fromProto(spec.sun_direction()));
    case pb::BakeSpec::kSunAngles:
      return LightFrame::fromElevationAzimuth(spec.sun_angles().elevation_deg(), spec.sun_angles().azimuth_deg());
    default: throw InputError("the spec names no sun: give sun_direction or sun_angles");
  }
}

std::string specToJson(const pb::BakeSpec& spec) {
  std::string out;
  google::protobuf::util::JsonPrintOptions options;
  options.add_whitespace = true;
  options.preserve_proto_field_names = true;
  (void)google::protobuf::util::MessageToJsonString(spec, &out, options);
  return out;
}

pb::BakeSpec specFromJson(const std::string& json, const std::string& source) {
  pb::BakeSpec spec;
  auto status = google::protobuf::util::JsonStringToMessage(json, &spec);
  if (!status.ok()) throw InputError(source + ": not a bake job: " + std::string(status.message()));
  return spec;
}

}  // namespace cpvs::net
