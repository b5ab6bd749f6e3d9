#include "cpvs/net/farm_model.h"

#include "cpvs/base/error.h"
#include "cpvs/net/convert.h"
#include "cpvs/net/model_convert.h"

namespace cpvs::net {

namespace {

/// An enum of the contract as the core's, InputError naming the field for a value the
/// core does not know (a newer client's, or garbage).
template <class Option>
Option optionOf(int value, const char* field) {
  if (!isOptionValue<Option>(value))
    throw InputError(std::string(field) + ": unknown value " + std::to_string(value));
  return Option(value);
}

pb::ReceiverBox toProto(const Box& b) {
  pb::ReceiverBox p;
  *p.mutable_min() = net::toProto(b.min);
  *p.mutable_max() = net::toProto(b.max);
  return p;
}

Box modelOf(const pb::ReceiverBox& b) { return {fromProto(b.min()), fromProto(b.max())}; }

pb::PlacePath toProto(const PlacePath& p) {
  pb::PlacePath o;
  o.set_latitude_deg(p.latitudeDeg);
  o.set_longitude_deg(p.longitudeDeg);
  o.set_height_m(p.heightM);
  o.set_start_utc(p.startUtc);
  o.set_end_utc(p.endUtc);
  o.set_step_seconds(p.stepSeconds);
  o.set_up(p.up);
  o.set_north(p.north);
  return o;
}

PlacePath modelOf(const pb::PlacePath& p) {
  return {p.latitude_deg(), p.longitude_deg(), p.height_m(), p.start_utc(), p.end_utc(), p.step_seconds(), p.up(),
          p.north()};
}

}  // namespace

bool isLightBundle(const BakeSpec& spec) { return !spec.lights.empty() || !spec.areaLights.empty() || spec.sceneLights; }

LightFrame lightOf(const BakeSpec& spec) {
  if (const Vec3* d = std::get_if<Vec3>(&spec.sun)) return LightFrame::fromDirection(*d);
  if (const SunAngles* a = std::get_if<SunAngles>(&spec.sun)) return LightFrame::fromElevationAzimuth(a->elevationDeg, a->azimuthDeg);
  throw InputError("the spec names no sun: give sun_direction or sun_angles");
}

const char* jobStateName(JobState s) {
  switch (s) {
    case JobState::Queued: return "queued";
    case JobState::Running: return "running";
    case JobState::Merging: return "merging";
    case JobState::Done: return "done";
    case JobState::Failed: return "failed";
    case JobState::Cancelled: return "cancelled";
    default: return "unknown";
  }
}

bool isFinalState(JobState s) { return s == JobState::Done || s == JobState::Failed || s == JobState::Cancelled; }

const char* trackStateName(TrackState s) {
  switch (s) {
    case TrackState::Active: return "active";
    case TrackState::Finished: return "finished";
    case TrackState::Cancelled: return "cancelled";
    default: return "unknown";
  }
}

static_assert(int(JobState::Queued) == pb::JOB_QUEUED && int(JobState::Running) == pb::JOB_RUNNING &&
              int(JobState::Merging) == pb::JOB_MERGING && int(JobState::Done) == pb::JOB_DONE &&
              int(JobState::Failed) == pb::JOB_FAILED && int(JobState::Cancelled) == pb::JOB_CANCELLED);
static_assert(int(TrackState::Active) == pb::TRACK_ACTIVE && int(TrackState::Finished) == pb::TRACK_FINISHED &&
              int(TrackState::Cancelled) == pb::TRACK_CANCELLED);

pb::Receivers toProto(const Receivers& r) {
  pb::Receivers p;
  p.set_kind(pb::ReceiverKind(r.kind));
  p.set_max_pcf(r.maxPcf);
  p.set_volume_scene_hash(r.volumeSceneHash);
  for (const Box& b : r.boxes) *p.add_boxes() = toProto(b);
  for (const Box& b : r.cameraRegions) *p.add_camera_regions() = toProto(b);
  p.set_view_distance(r.viewDistance);
  for (const Vec3& v : r.cameraPoints) *p.add_camera_points() = toProto(v);
  for (const auto& path : r.cameraPaths) {
    pb::CameraPath& c = *p.add_camera_paths();
    for (const Vec3& v : path) *c.add_points() = toProto(v);
  }
  p.set_camera_visibility(pb::CameraVisibility(r.cameraVisibility));
  p.set_camera_spacing(r.cameraSpacing);
  p.set_camera_rays(r.cameraRays);
  p.set_ground_layer(r.groundLayer);
  if (r.groundSlopeDeg) p.set_ground_slope_deg(*r.groundSlopeDeg);
  p.set_ground_layer_from(r.groundLayerFrom);
  return p;
}

Receivers modelOf(const pb::Receivers& p) {
  Receivers r;
  r.kind = optionOf<ReceiverKind>(p.kind(), "options.receivers.kind");
  r.maxPcf = p.max_pcf();
  r.volumeSceneHash = p.volume_scene_hash();
  for (const auto& b : p.boxes()) r.boxes.push_back(modelOf(b));
  for (const auto& b : p.camera_regions()) r.cameraRegions.push_back(modelOf(b));
  r.viewDistance = p.view_distance();
  for (const auto& v : p.camera_points()) r.cameraPoints.push_back(fromProto(v));
  for (const auto& path : p.camera_paths()) {
    r.cameraPaths.emplace_back();
    for (const auto& v : path.points()) r.cameraPaths.back().push_back(fromProto(v));
  }
  r.cameraVisibility = optionOf<CameraVisibility>(p.camera_visibility(), "options.receivers.camera_visibility");
  r.cameraSpacing = p.camera_spacing();
  r.cameraRays = p.camera_rays();
  r.groundLayer = p.ground_layer();
  if (p.has_ground_slope_deg()) r.groundSlopeDeg = p.ground_slope_deg();
  r.groundLayerFrom = p.ground_layer_from();
  return r;
}

pb::BakeOptions toProto(const JobOptions& o) {
  pb::BakeOptions p;
  p.set_closed(pb::ClosedMode(o.closed));
  p.set_exit(pb::ExitMode(o.exit));
  p.set_no_cull(!o.cull);
  p.set_compress(pb::CompressMode(o.compress));
  p.set_undefined_rule(pb::UndefinedRule(o.undefinedRule));
  p.set_tile_size(o.tileSize);
  p.set_depth_slices(o.depthSlices);
  if (o.renderer) p.set_renderer(pb::Renderer(*o.renderer));
  if (o.receivers) *p.mutable_receivers() = toProto(*o.receivers);
  return p;
}

JobOptions modelOf(const pb::BakeOptions& p) {
  JobOptions o;
  o.closed = optionOf<ClosedMode>(p.closed(), "options.closed");
  o.exit = optionOf<ExitMode>(p.exit(), "options.exit");
  o.cull = !p.no_cull();
  o.compress = optionOf<CompressMode>(p.compress(), "options.compress");
  o.undefinedRule = p.has_undefined_rule() ? optionOf<UndefinedRule>(p.undefined_rule(), "options.undefined_rule")
                                            : UndefinedRule::New;  // an older client's
  o.tileSize = p.tile_size();
  o.depthSlices = p.depth_slices();
  if (p.has_renderer()) o.renderer = optionOf<Renderer>(p.renderer(), "options.renderer");
  if (p.has_receivers()) o.receivers = modelOf(p.receivers());
  return o;
}

BakeOptions bakeOptionsOf(const JobOptions& options) { return fromProto(toProto(options)); }

pb::BakeSpec toProto(const BakeSpec& s) {
  pb::BakeSpec p;
  p.set_scene_hash(s.sceneHash);
  if (const Vec3* d = std::get_if<Vec3>(&s.sun)) *p.mutable_sun_direction() = toProto(*d);
  if (const SunAngles* a = std::get_if<SunAngles>(&s.sun)) {
    p.mutable_sun_angles()->set_elevation_deg(a->elevationDeg);
    p.mutable_sun_angles()->set_azimuth_deg(a->azimuthDeg);
  }
  p.set_resolution(s.resolution);
  *p.mutable_options() = toProto(s.options);  // always: it names the undefined rule (absent there: new)
  p.set_priority(s.priority);
  p.set_name(s.name);
  for (const Light& l : s.lights) *p.add_lights() = toProto(l);
  p.set_scene_lights(s.sceneLights);
  p.set_footprint(s.footprint);
  if (s.pointerGrid) p.set_pointer_grid(*s.pointerGrid);
  for (const MediumSpec& m : s.media) {
    pb::Medium& q = *p.add_media();
    q.set_name(m.name);
    q.set_scattering(m.scattering);
    q.set_absorption(m.absorption);
    q.set_g(m.g);
  }
  for (const AreaLight& a : s.areaLights) *p.add_area_lights() = toProto(a);
  p.set_format(s.format == ArtifactFormat::DagMh ? pb::ARTIFACT_FORMAT_DAG_MH : pb::ARTIFACT_FORMAT_CPVS);
  return p;
}

BakeSpec modelOf(const pb::BakeSpec& p) {
  BakeSpec s;
  s.sceneHash = p.scene_hash();
  if (p.has_sun_direction()) s.sun = fromProto(p.sun_direction());
  if (p.has_sun_angles()) s.sun = SunAngles{p.sun_angles().elevation_deg(), p.sun_angles().azimuth_deg()};
  s.resolution = p.resolution();
  s.options = modelOf(p.options());
  s.priority = p.priority();
  s.name = p.name();
  if (size_t(p.lights_size()) > kMaxLights) checkLightCount(size_t(p.lights_size()));
  for (int i = 0; i < p.lights_size(); ++i) {
    try {
      if (p.lights(i).kind() == pb::LIGHT_SPOT && !p.lights(i).has_direction())
        throw InputError("a spot light needs a direction");
      s.lights.push_back(fromProto(p.lights(i)));
    } catch (const InputError& e) {
      throw InputError("lights[" + std::to_string(i) + "]: " + e.what());
    }
  }
  s.sceneLights = p.scene_lights();
  s.footprint = p.footprint();
  if (p.has_pointer_grid()) s.pointerGrid = p.pointer_grid();
  for (const auto& m : p.media()) s.media.push_back({m.name(), m.scattering(), m.absorption(), m.g()});
  s.areaLights = areaLightsOf(p);
  switch (p.format()) {
    case pb::ARTIFACT_FORMAT_CPVS: s.format = ArtifactFormat::Cpvs; break;
    case pb::ARTIFACT_FORMAT_DAG_MH: s.format = ArtifactFormat::DagMh; break;
    default: throw InputError("format " + std::to_string(int(p.format())) + " is not one this build knows (cpvs, dagmh)");
  }
  return s;
}

const char* formatName(ArtifactFormat f) { return f == ArtifactFormat::DagMh ? "dagmh" : "cpvs"; }

ArtifactFormat parseFormat(const std::string& name, const std::string& what) {
  if (name == "cpvs") return ArtifactFormat::Cpvs;
  if (name == "dagmh") return ArtifactFormat::DagMh;
  throw InputError(what + " '" + name + "': cpvs or dagmh");
}

JobStatus modelOf(const pb::JobStatus& p) {
  JobStatus s;
  s.jobId = p.job_id();
  s.requestId = p.request_id();
  s.state = p.state() >= pb::JOB_QUEUED && p.state() <= pb::JOB_CANCELLED ? JobState(p.state()) : JobState::Unspecified;
  s.spec = modelOf(p.spec());
  s.tilesTotal = p.tiles_total();
  s.tilesDone = p.tiles_done();
  s.tilesUntouched = p.tiles_untouched();
  s.tilesUnread = p.tiles_unread();
  s.tilesReused = p.tiles_reused();
  for (const auto& st : p.stages()) s.stages.push_back({st.stage(), st.seconds()});
  s.secondsElapsed = p.seconds_elapsed();
  s.etaSeconds = p.eta_seconds();
  s.error = p.error();
  s.bytes = p.bytes();
  s.fileBytes = p.file_bytes();
  s.resolution = p.resolution();
  s.peakMergeBytes = p.peak_merge_bytes();
  s.createdUnixMs = p.created_unix_ms();
  s.lights = p.lights();
  s.grids = p.grids();
  return s;
}

pb::TrackSpec toProto(const TrackSpec& s) {
  pb::TrackSpec p;
  p.set_scene_hash(s.sceneHash);
  p.set_resolution(s.resolution);
  *p.mutable_options() = toProto(s.options);  // always: it names the undefined rule (absent there: new)
  p.set_name(s.name);
  if (const PlacePath* place = std::get_if<PlacePath>(&s.path)) *p.mutable_place() = toProto(*place);
  if (const auto* directions = std::get_if<std::vector<Vec3>>(&s.path)) {
    pb::DirectionList& list = *p.mutable_directions();
    for (const Vec3& d : *directions) *list.add_directions() = toProto(d);
  }
  if (const ClockPath* clock = std::get_if<ClockPath>(&s.path)) {
    *p.mutable_clock()->mutable_place() = toProto(clock->place);
    p.mutable_clock()->set_rate(clock->rate);
  }
  p.set_keyframes_ahead(s.keyframesAhead);
  p.set_keep_versions(s.keepVersions);
  return p;
}

TrackSpec modelOf(const pb::TrackSpec& p) {
  TrackSpec s;
  s.sceneHash = p.scene_hash();
  s.resolution = p.resolution();
  s.options = modelOf(p.options());
  s.name = p.name();
  switch (p.path_case()) {
    case pb::TrackSpec::kPlace: s.path = modelOf(p.place()); break;
    case pb::TrackSpec::kDirections: {
      std::vector<Vec3> directions;
      for (const auto& d : p.directions().directions()) directions.push_back(fromProto(d));
      s.path = std::move(directions);
      break;
    }
    case pb::TrackSpec::kClock: s.path = ClockPath{modelOf(p.clock().place()), p.clock().rate()}; break;
    default: break;
  }
  s.keyframesAhead = p.keyframes_ahead();
  s.keepVersions = p.keep_versions();
  return s;
}

TrackStatus modelOf(const pb::TrackStatus& p) {
  TrackStatus s;
  s.trackId = p.track_id();
  s.requestId = p.request_id();
  s.state = p.state() >= pb::TRACK_ACTIVE && p.state() <= pb::TRACK_CANCELLED ? TrackState(p.state())
                                                                               : TrackState::Unspecified;
  s.spec = modelOf(p.spec());
  s.keyframesTotal = p.keyframes_total();
  s.keyframesPublished = p.keyframes_published();
  s.keyframesSkipped = p.keyframes_skipped();
  s.latestSequence = p.latest_sequence();
  s.error = p.error();
  s.createdUnixMs = p.created_unix_ms();
  return s;
}

TrackVersion modelOf(const pb::TrackVersion& p) {
  return {p.track_id(),           p.sequence(), p.keyframe(), p.instant_unix_ms(), fromProto(p.sun_direction()),
          p.job_id(),             p.checksum(), p.file_bytes()};
}

BakeSpec bakeSpecFromJson(const std::string& json, const std::string& source) {
  const pb::BakeSpec spec = specFromJson(json, source);
  try {
    BakeSpec model = modelOf(spec);
    // A job file is written for this version: without a rule, its default.
    if (!spec.options().has_undefined_rule()) model.options.undefinedRule = JobOptions{}.undefinedRule;
    return model;
  } catch (const InputError& e) {
    throw InputError(source + ": " + e.what());
  }
}

std::string toJson(const BakeSpec& spec) { return specToJson(toProto(spec)); }

}  // namespace cpvs::net
