#include "farm_convert.h"

#include <google/protobuf/util/json_util.h>
#include <xxhash.h>

#include <cmath>

namespace cpvs::farm {

pb::Vec3 toProto(const Vec3& v) {
  pb::Vec3 p;
  p.set_x(v.x);
  p.set_y(v.y);
  p.set_z(v.z);
  return p;
}

Vec3 fromProto(const pb::Vec3& v) { return {v.x(), v.y(), v.z()}; }

pb::BakeOptions toProto(const BakeOptions& o) {
  pb::BakeOptions p;
  p.set_closed(pb::ClosedMode(int(o.closed)));
  p.set_exit(pb::ExitMode(int(o.exit)));
  p.set_no_cull(!o.cull);
  p.set_compress(pb::CompressMode(int(o.compress)));
  p.set_undefined_rule(pb::UndefinedRule(int(o.undefinedRule)));
  p.set_tile_size(1u << o.log2TileSize);
  return p;
}

BakeOptions fromProto(const pb::BakeOptions& p) {
  BakeOptions o;
  if (p.closed() < 0 || p.closed() > 2) throw InputError("options.closed: unknown value " + std::to_string(p.closed()));
  if (p.exit() < 0 || p.exit() > 1) throw InputError("options.exit: unknown value " + std::to_string(p.exit()));
  if (p.compress() < 0 || p.compress() > 2)
    throw InputError("options.compress: unknown value " + std::to_string(p.compress()));
  if (p.undefined_rule() < 0 || p.undefined_rule() > 1)
    throw InputError("options.undefined_rule: unknown value " + std::to_string(p.undefined_rule()));
  o.closed = ClosedMode(p.closed());
  o.exit = ExitMode(p.exit());
  o.cull = !p.no_cull();
  o.compress = CompressMode(p.compress());
  o.undefinedRule = UndefinedRule(p.undefined_rule());
  uint32_t t = p.tile_size() == 0 ? 4096 : p.tile_size();
  if (t < 8 || t > 65536 || (t & (t - 1)) != 0)
    throw InputError("options.tile_size " + std::to_string(p.tile_size()) + " must be a power of two in 8..65536");
  o.log2TileSize = 0;
  while ((1u << o.log2TileSize) < t) ++o.log2TileSize;
  return o;
}

pb::GridSpec toProto(const Grid& g) {
  pb::GridSpec p;
  *p.mutable_light_dir() = toProto(g.frame.dir);
  *p.mutable_frame_u() = toProto(g.frame.u);
  *p.mutable_frame_v() = toProto(g.frame.v);
  p.set_log2_resolution(uint32_t(g.log2Resolution));
  *p.mutable_origin() = toProto(g.origin);
  p.set_u0(g.u0);
  p.set_v0(g.v0);
  p.set_d0(g.d0);
  p.set_extent(g.extent);
  p.set_depth_extent(g.depthExtent);
  return p;
}

Grid fromProto(const pb::GridSpec& p) {
  Grid g;
  g.frame.dir = fromProto(p.light_dir());
  g.frame.u = fromProto(p.frame_u());
  g.frame.v = fromProto(p.frame_v());
  g.origin = fromProto(p.origin());
  g.u0 = p.u0();
  g.v0 = p.v0();
  g.d0 = p.d0();
  g.extent = p.extent();
  g.depthExtent = p.depth_extent();
  if (p.log2_resolution() < uint32_t(kMinLog2Resolution) || p.log2_resolution() > uint32_t(kMaxLog2Resolution))
    throw InputError("grid.log2_resolution " + std::to_string(p.log2_resolution()) + " is out of range");
  g.log2Resolution = int(p.log2_resolution());
  for (const Vec3* v : {&g.frame.dir, &g.frame.u, &g.frame.v, &g.origin})
    if (!isFinite(*v)) throw InputError("grid: the light frame holds a non-finite value");
  for (double v : {g.u0, g.v0, g.d0, g.extent, g.depthExtent})
    if (!std::isfinite(v)) throw InputError("grid holds a non-finite value");
  if (!(g.extent > 0) || !(g.depthExtent > 0)) throw InputError("grid extents must be positive");
  if (std::abs(length(g.frame.dir) - 1) > 1e-9) throw InputError("grid.light_dir is not a unit vector");
  return g;
}

LightFrame lightOf(const pb::BakeSpec& spec) {
  switch (spec.sun_case()) {
    case pb::BakeSpec::kSunDirection: return LightFrame::fromDirection(fromProto(spec.sun_direction()));
    case pb::BakeSpec::kSunAngles:
      return LightFrame::fromElevationAzimuth(spec.sun_angles().elevation_deg(), spec.sun_angles().azimuth_deg());
    default: throw InputError("the spec names no sun: give sun_direction or sun_angles");
  }
}

Hash128 parseHashHex(const std::string& text, const std::string& what) {
  if (text.size() != 32) throw InputError(what + " '" + text + "' is not 32 hexadecimal digits");
  Hash128 h;
  for (int half = 0; half < 2; ++half) {
    uint64_t v = 0;
    for (int i = 0; i < 16; ++i) {
      char c = text[size_t(half * 16 + i)];
      int d = c >= '0' && c <= '9' ? c - '0' : (c >= 'a' && c <= 'f' ? c - 'a' + 10 : -1);
      if (d < 0) throw InputError(what + " '" + text + "' is not 32 lower-case hexadecimal digits");
      v = v << 4 | uint64_t(d);
    }
    (half == 0 ? h.hi : h.lo) = v;
  }
  return h;
}

Hash128 contentHash(const void* data, size_t size) {
  XXH128_hash_t h = XXH3_128bits(data, size);
  return Hash128{h.low64, h.high64};
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

const char* jobStateName(pb::JobState s) {
  switch (s) {
    case pb::JOB_QUEUED: return "queued";
    case pb::JOB_RUNNING: return "running";
    case pb::JOB_MERGING: return "merging";
    case pb::JOB_DONE: return "done";
    case pb::JOB_FAILED: return "failed";
    case pb::JOB_CANCELLED: return "cancelled";
    default: return "unknown";
  }
}

}  // namespace cpvs::farm
