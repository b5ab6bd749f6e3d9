// `cpvs submit | jobs | watch | cancel | download | track | subscribe`: the bake farm from
// the command line.
// The transport is FarmClient; this file parses, prints and chooses exit statuses:
// 0 success, 1 the job failed or was cancelled, 2 bad input or a request the farm refused,
// 4 the farm could not be reached.
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <thread>

#include "bake_flags.h"
#include "cli_util.h"
#include "commands.h"
#include "cpvs/bake/bake_lights.h"
#include "cpvs/base/error.h"
#include "cpvs/scene/import.h"
#include "cpvs/net/receiver_declaration.h"
#include "cpvs/bake/stage_times.h"
#include "cpvs/scene/obj_writer.h"
#include "cpvs/base/parse.h"
#include "cpvs/base/text.h"
#include "cpvs/dag/packed_layout.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/light/frame.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/scene/source.h"
#include "cpvs/client/farm_client.h"
#include "cpvs/net/farm_model.h"
#include "cpvs/query/normal_offset.h"
#include "cpvs/sun/sun_position.h"

namespace cpvs::cli {

using client::FarmCallError;
using client::FarmClient;
using client::isFinalState;
using client::randomRequestId;
using net::BakeSpec;
using net::JobOptions;
using net::JobState;
using net::JobStatus;

namespace {

namespace fs = std::filesystem;

// --- shared -----------------------------------------------------------------------------

struct ConnectionArgs {
  std::string server, token, ca;
  bool allowPlaintextToken = false;
};

void addConnectionOptions(CLI::App* c, ConnectionArgs& a) {
  c->add_option("--server", a.server, "Coordinator HOST:PORT")->required();
  c->add_option("--token", a.token, "Bearer token (default: $CPVS_TOKEN)");
  c->add_option("--ca", a.ca, "PEM roots to trust: connect with TLS (plaintext without)");
  c->add_flag("--allow-plaintext-token", a.allowPlaintextToken,
              "Send the token without TLS to a coordinator that is not on this machine (a trusted private network)");
}

net::Connection connectionOf(const ConnectionArgs& a) {
  net::Connection c{a.server, a.token, a.ca, a.allowPlaintextToken};
  if (c.token.empty())
    if (const char* t = std::getenv("CPVS_TOKEN")) c.token = t;
  // Tokens often come from files or secrets with a trailing newline.
  while (!c.token.empty() && std::isspace(static_cast<unsigned char>(c.token.back()))) c.token.pop_back();
  return c;
}

/// Runs a farm command and stores its exit status; a failed RPC prints its status and
/// exits with 2 when the caller can fix the request, 4 otherwise. Other errors go on to main().
template <class F>
void runFarmCommand(int& status, F&& body) {
  try {
    status = body();
  } catch (const FarmCallError& e) {
    std::fprintf(stderr, "cpvs: %s\n", loggable(e.what(), 2000).c_str());
    status = e.callerCanFix() ? 2 : 4;
  }
}

/// A line for the person at the terminal, on stderr so that stdout stays parseable.
void note(bool quiet, const std::string& text) {
  if (!quiet) std::fprintf(stderr, "%s\n", text.c_str());
}

/// Stage times summed by name, in the pipeline's order, then any others by name.
std::vector<std::pair<std::string, double>> stagesOf(const JobStatus& s) {
  std::map<std::string, double> sum;
  for (const auto& st : s.stages) sum[st.stage] += st.seconds;
  std::vector<std::pair<std::string, double>> out;
  for (const char* name : kStageNames) {
    auto it = sum.find(name);
    if (it == sum.end()) continue;
    out.emplace_back(*it);
    sum.erase(it);
  }
  out.insert(out.end(), sum.begin(), sum.end());
  return out;
}

/// A job status as a JSON object. `out` is the artifact's path for submit and watch
/// (null when there is none); `withOut` false leaves the key away (listings).
std::string statusJson(const JobStatus& s, const std::string& indent, bool withOut, const std::string& out = {}) {
  const std::string in = indent + "  ";
  std::ostringstream o;
  o << "{\n"
    << in << "\"job\": " << jsonString(s.jobId) << ",\n"
    << in << "\"request_id\": " << jsonString(s.requestId) << ",\n"
    << in << "\"name\": " << jsonString(s.spec.name) << ",\n"
    << in << "\"scene_hash\": " << jsonString(s.spec.sceneHash) << ",\n"
    << in << "\"state\": " << jsonString(net::jobStateName(s.state)) << ",\n"
    << in << "\"format\": " << jsonString(net::formatName(s.spec.format)) << ",\n"
    << in << "\"priority\": " << s.spec.priority << ",\n"
    << in << "\"resolution\": " << s.resolution << ",\n"
    << in << "\"lights\": " << s.lights << ",\n"
    << in << "\"grids\": " << s.grids << ",\n"
    << in << "\"tiles\": " << s.tilesTotal << ",\n"
    << in << "\"tiles_done\": " << s.tilesDone << ",\n"
    << in << "\"tiles_untouched\": " << s.tilesUntouched << ",\n"
    << in << "\"tiles_unread\": " << s.tilesUnread << ",\n"
    << in << "\"tiles_reused\": " << s.tilesReused << ",\n"
    << in << "\"bytes\": " << s.bytes << ",\n"
    << in << "\"file_bytes\": " << s.fileBytes << ",\n"
    << in << "\"peak_merge_bytes\": " << s.peakMergeBytes << ",\n"
    << in << "\"seconds_total\": " << jsonNumber(s.secondsElapsed) << ",\n"
    << in << "\"eta_seconds\": " << (s.etaSeconds < 0 ? "null" : jsonNumber(s.etaSeconds)) << ",\n"
    << in << "\"created_unix_ms\": " << s.createdUnixMs << ",\n"
    << in << "\"stages\": {";
  bool first = true;
  for (const auto& [stage, seconds] : stagesOf(s)) {
    o << (first ? "" : ", ") << jsonString(stage) << ": " << jsonNumber(seconds);
    first = false;
  }
  o << "},\n" << in << "\"error\": " << jsonString(s.error);
  if (withOut) o << ",\n" << in << "\"out\": " << (out.empty() ? "null" : jsonString(out));
  o << "\n" << indent << "}";
  return o.str();
}

/// Follows a job to its end with a progress bar (stage = state, counts = tiles).
JobStatus followJob(FarmClient& client, const std::string& jobId, bool show) {
  ProgressDisplay progress(show);
  JobStatus final = client.watch(jobId, [&](const JobStatus& s) {
    // The coordinator's ETA (from its running tiles' rate), not one made up here.
    progress.update({net::jobStateName(s.state), s.tilesDone, s.tilesTotal, s.etaSeconds});
  });
  progress.finish();
  return final;
}

void printDone(const JobStatus& s) {
  const uint64_t R = s.grids ? 0 : s.resolution;  // a bundle's grids have resolutions of their own
  if (s.grids)
    std::printf("Job %s done: a light bundle of %u light%s in %u grids (the finest %llu^2), %llu tile%s, %.2f s\n",
                loggable(s.jobId).c_str(), s.lights, s.lights == 1 ? "" : "s", s.grids,
                static_cast<unsigned long long>(s.resolution), static_cast<unsigned long long>(s.tilesTotal),
                s.tilesTotal == 1 ? "" : "s", s.secondsElapsed);
  else if (s.spec.format == net::ArtifactFormat::DagMh)
    std::printf("Job %s done: a DAG-MH of %llu^2 texels in %llu tile%s, %.2f s\n", loggable(s.jobId).c_str(),
                static_cast<unsigned long long>(R), static_cast<unsigned long long>(s.tilesTotal),
                s.tilesTotal == 1 ? "" : "s", s.secondsElapsed);
  else
    std::printf("Job %s done: %llu^3 in %llu tile%s, %.2f s\n", loggable(s.jobId).c_str(),
                static_cast<unsigned long long>(R), static_cast<unsigned long long>(s.tilesTotal),
                s.tilesTotal == 1 ? "" : "s", s.secondsElapsed);
  if (s.tilesUntouched + s.tilesUnread > 0)
    std::printf("  %llu tiles all lit, never leased: %llu touched by no triangle, %llu read by no receiver\n",
                static_cast<unsigned long long>(s.tilesUntouched + s.tilesUnread),
                static_cast<unsigned long long>(s.tilesUntouched), static_cast<unsigned long long>(s.tilesUnread));
  if (s.tilesReused > 0)
    std::printf("  %llu tiles sent from the workers' tile caches (their content was baked before), %llu baked\n",
                static_cast<unsigned long long>(s.tilesReused),
                static_cast<unsigned long long>(s.tilesTotal - s.tilesUntouched - s.tilesUnread - s.tilesReused));
  auto stages = stagesOf(s);
  if (!stages.empty()) {
    std::printf("\n  %-10s %10s\n", "stage", "seconds");
    for (const auto& [stage, seconds] : stages) std::printf("  %-10s %10.3f\n", stage.c_str(), seconds);
    std::printf("  (tile stages are summed over the workers)\n");
  }
  std::printf("\n  %s: %s (%llu bytes), file: %s, largest merge held: %s\n",
              s.spec.format == net::ArtifactFormat::DagMh ? "DAG-MH" : "DAG", humanBytes(s.bytes).c_str(),
              static_cast<unsigned long long>(s.bytes), humanBytes(s.fileBytes).c_str(),
              humanBytes(s.peakMergeBytes).c_str());
  if (R > 0 && s.bytes > 0) {
    uint64_t sm = R * R * 2;
    std::printf("  16-bit shadow map of %llu^2: %s, %.1fx larger than the DAG\n", static_cast<unsigned long long>(R),
                humanBytes(sm).c_str(), double(sm) / double(s.bytes));
  }
}

/// What a final status means for the exit status: 0 done, 1 failed or cancelled (with a
/// message on stderr).
int finalExitStatus(const JobStatus& s) {
  if (s.state == JobState::Failed) {
    std::fprintf(stderr, "cpvs: job %s failed: %s\n", loggable(s.jobId).c_str(), loggable(s.error, 2000).c_str());
    return 1;
  }
  if (s.state == JobState::Cancelled) {
    std::fprintf(stderr, "cpvs: job %s was cancelled\n", loggable(s.jobId).c_str());
    return 1;
  }
  return 0;
}

// --- submit -----------------------------------------------------------------------------

/// Each option flag given on the command line overrides its field of `o`; checked after.
/// Returns the receiver volume's mesh file to upload (`--receivers volume:MESH`), or "".
std::string applyOptionFlags(const OptionFlags& options, const CLI::App& c, JobOptions& o) {
  auto given = [&](const char* option) { return c.count(option) > 0; };
  const BakeOptions flags = optionsOf(options);
  if (given("--closed")) o.closed = flags.closed;
  if (given("--exit")) o.exit = flags.exit;
  if (given("--cull")) o.cull = flags.cull;
  if (given("--compress")) o.compress = flags.compress;
  if (given("--undefined")) o.undefinedRule = flags.undefinedRule;
  if (given("--tile-size")) o.tileSize = uint32_t(1) << flags.log2TileSize;
  if (given("--depth-slices")) {
    if (options.depthSlices > (uint64_t(1) << kMaxLog2Resolution))
      throw InputError("--depth-slices " + std::to_string(options.depthSlices) + " is more than the largest resolution");
    o.depthSlices = uint32_t(options.depthSlices);
  }
  if (given("--renderer")) o.renderer = flags.renderer;
  std::string mesh;
  if (given("--receivers") || given("--receiver-box") || given("--receiver-pcf") || given("--ground-layer") ||
      given("--ground-slope") || cameraFlagsGiven(options)) {
    net::Receivers& r = o.receivers ? *o.receivers : o.receivers.emplace();
    bool cameraFile = false;
    if (given("--receivers")) {
      r.kind = flags.receivers;
      r.volumeSceneHash.clear();
      const size_t colon = options.receivers.find(':');
      if (colon != std::string::npos) mesh = options.receivers.substr(colon + 1);
      if (!mesh.empty() && flags.receivers != ReceiverKind::Volume && flags.receivers != ReceiverKind::Cameras)
        throw InputError("--receivers: only 'volume' and 'cameras' take a file ('" + options.receivers + "')");
      // A camera file sets every camera field; the camera flags then add to it or override.
      if (flags.receivers == ReceiverKind::Cameras && net::isCameraFile(mesh)) {
        net::copyCameras(net::readCameraFile(mesh), r);
        mesh.clear();
        cameraFile = true;
      }
    }
    if (given("--receiver-pcf")) {
      checkPcfWidth(options.receiverPcf);
      r.maxPcf = uint32_t(options.receiverPcf);
    }
    if (given("--receiver-box")) {
      r.boxes.clear();
      for (const auto& [lo, hi] : boxesOf(options.receiverBoxes, "--receiver-box")) r.boxes.push_back({lo, hi});
    }
    if (given("--camera-region")) {
      if (!cameraFile) r.cameraRegions.clear();
      for (const auto& [lo, hi] : boxesOf(options.cameraRegions, "--camera-region")) r.cameraRegions.push_back({lo, hi});
    }
    if (given("--view-distance")) r.viewDistance = options.viewDistance;
    if (given("--camera-visibility"))
      r.cameraVisibility = parseOption<CameraVisibility>(options.cameraVisibility, "--camera-visibility");
    if (given("--camera-spacing")) r.cameraSpacing = options.cameraSpacing;
    if (given("--camera-rays")) {
      if (options.cameraRays < 0) throw InputError("--camera-rays must be 0 (the default, 128) or more");
      r.cameraRays = uint32_t(options.cameraRays);
    }
    if (given("--ground-layer")) std::tie(r.groundLayerFrom, r.groundLayer) = groundLayerOf(options.groundLayer);
    if (given("--ground-slope")) r.groundSlopeDeg = options.groundSlope;
  }
  // A mesh still to upload stands for the hash it will have.
  JobOptions check = o;
  if (!mesh.empty()) check.receivers->volumeSceneHash = std::string(32, '0');
  (void)net::bakeOptionsOf(check);
  return mesh;
}

/// Uploads the receiver volume's mesh (if the flags named one) and records its hash.
void uploadReceiverVolume(FarmClient& client, const std::string& mesh, JobOptions& o) {
  if (mesh.empty()) return;
  o.receivers->volumeSceneHash = client.uploadScene(mesh).sceneHash;
}

struct SubmitArgs {
  ConnectionArgs conn;
  std::string scene, jobFile, requestId, name, out;
  std::string resolution = "4K";
  SunFlags sun;
  LightFlags lights;
  int pointerGrid = kMaxGridLevels;
  std::string format;
  OptionFlags options;
  int priority = 0;
  bool wait = false, json = false, quiet = false;
};

bool isGeneratedScene(const std::string& scene) {
  return scene == "city" || scene.starts_with("city:") || scene == "landscape" || scene.starts_with("landscape:");
}

/// A generated scene written to a temporary OBJ file (positions with full double
/// precision), removed with its folder when this goes out of scope.
class TemporaryScene {
 public:
  explicit TemporaryScene(const std::string& spec) {
    scene_ = openScene(spec);
    std::string pattern = (fs::temp_directory_path() / "cpvs-scene-XXXXXX").string();
    if (!::mkdtemp(pattern.data())) throw InputError("cannot create a temporary folder: " + std::string(std::strerror(errno)));
    dir_ = pattern;
    std::string base = spec;
    for (char& ch : base)
      if (ch == ':') ch = '-';
    path_ = (fs::path(dir_) / (base + ".obj")).string();
    writeObj(path_, scene_, spec + ", generated by cpvs");
  }
  ~TemporaryScene() {
    std::error_code ignored;
    fs::remove_all(dir_, ignored);
  }
  TemporaryScene(const TemporaryScene&) = delete;
  TemporaryScene& operator=(const TemporaryScene&) = delete;

  const std::string& path() const { return path_; }
  /// The generated scene, whose point and spot lights an OBJ cannot carry.
  const Scene& scene() const { return scene_; }

 private:
  Scene scene_;
  std::string dir_, path_;
};

void buildSun(const SubmitArgs& a, const CLI::App& c, BakeSpec& spec);

/// The spec to submit: the job file's, if any, with every flag given on the command line
/// overriding its field, and the bake defaults for what neither gives. Validated here,
/// before anything is uploaded; InputError names the flag or field.
BakeSpec buildSpec(const SubmitArgs& a, const CLI::App& c, std::string& volumeMesh) {
  auto given = [&](const char* option) { return c.count(option) > 0; };
  BakeSpec spec;
  if (!a.jobFile.empty()) {
    std::vector<uint8_t> bytes = readFile(a.jobFile);
    spec = net::bakeSpecFromJson(std::string(bytes.begin(), bytes.end()), a.jobFile);
  }

  // Local lights: the flags replace the job file's lights (or add the scene's).
  if (!a.lights.spots.empty() || !a.lights.points.empty() || !a.lights.lightsFile.empty() || !a.lights.areas.empty()) {
    // The farm expands the area lights into their VPLs as `cpvs bake` does.
    LightFlags own = a.lights;
    own.areas.clear();
    spec.lights.clear();
    if (!own.spots.empty() || !own.points.empty() || !own.lightsFile.empty()) spec.lights = flagLights(own);
    spec.areaLights = flagAreaLights(a.lights);
  }
  if (a.lights.sceneLights) spec.sceneLights = true;
  if (given("--footprint")) {
    if (!(a.lights.footprint > 0) || !std::isfinite(a.lights.footprint))
      throw InputError("--footprint must be a finite width > 0");
    spec.footprint = a.lights.footprint;
  }
  if (given("--pointer-grid")) {
    if (a.pointerGrid < 0 || a.pointerGrid > kMaxGridLevels)
      throw InputError("--pointer-grid " + std::to_string(a.pointerGrid) + ": levels 0 to " + std::to_string(kMaxGridLevels));
    spec.pointerGrid = uint32_t(a.pointerGrid);
  }
  if (given("--format")) spec.format = net::parseFormat(a.format, "--format");
  if (net::isLightBundle(spec)) {
    if (spec.format != net::ArtifactFormat::Cpvs)
      throw InputError("--format dagmh bakes the sun: local lights bake into a light bundle (--format cpvs)");
    checkNoSunWithLights(a.sun);
    if (!std::holds_alternative<std::monostate>(spec.sun))
      throw InputError("local lights make a light bundle: " + a.jobFile + " names a sun too");
    if (given("--resolution"))
      throw InputError("--resolution is the sun's: give a light's own in a lights file, or --footprint");
    for (size_t i = 0; i < spec.lights.size(); ++i)
      if (spec.lights[i].area != 0)
        throw InputError("lights[" + std::to_string(i) + "]: an area number is the farm's to give the VPLs of "
                         "area_lights; submit the area light there");
  } else {
    if (spec.pointerGrid || spec.footprint != 0)
      throw InputError("--pointer-grid and --footprint are for local lights (--spot, --point, --lights, --scene-lights)");
    buildSun(a, c, spec);
  }
  volumeMesh = applyOptionFlags(a.options, c, spec.options);
  for (const BakePlan::Medium& m : declaredMedia(a.options))
    spec.media.push_back({m.name, m.scattering, m.absorption, m.g});

  if (given("--priority")) spec.priority = a.priority;
  if (given("--name")) spec.name = a.name;
  if (spec.name.empty() && !a.scene.empty())
    spec.name = isGeneratedScene(a.scene) ? a.scene : fs::path(a.scene).filename().string();
  if (a.scene.empty() && spec.sceneHash.empty())
    throw InputError("give the SCENE to bake (a file or city[:BLOCKS[:SEED]]), or a scene_hash in the job file");
  return spec;
}

/// The sun and resolution of a sun bake's spec, from the flags over the job file's.
void buildSun(const SubmitArgs& a, const CLI::App& c, BakeSpec& spec) {
  auto given = [&](const char* option) { return c.count(option) > 0; };
  const bool dir = given("--sun-dir"), elevation = given("--sun-elevation"), azimuth = given("--sun-azimuth");
  if (dir && (elevation || azimuth))
    throw InputError("give either --sun-dir or --sun-elevation/--sun-azimuth, not both");
  if (dir) {
    spec.sun = parseVec3(a.sun.dir, "--sun-dir");
  } else if (elevation || azimuth) {
    const net::SunAngles* fromFile = std::get_if<net::SunAngles>(&spec.sun);
    if (!elevation && !fromFile)
      throw InputError("--sun-azimuth needs --sun-elevation (or sun_angles in the job file)");
    net::SunAngles angles = fromFile ? *fromFile : net::SunAngles{};
    if (elevation) angles.elevationDeg = a.sun.elevation;
    if (azimuth) angles.azimuthDeg = a.sun.azimuth;
    spec.sun = angles;
  }
  if (std::holds_alternative<std::monostate>(spec.sun))
    throw InputError(std::string("give the light: --sun-dir X,Y,Z or --sun-elevation DEG, or local lights (--spot, "
                                 "--point, --lights, --scene-lights)") +
                     (a.jobFile.empty() ? "" : " (or sun_direction, sun_angles or lights in " + a.jobFile + ")"));
  (void)net::lightOf(spec);

  if (given("--resolution") || spec.resolution.empty()) spec.resolution = a.resolution;
  (void)parseResolution(spec.resolution);
}

int runSubmit(const SubmitArgs& a, const CLI::App& c) {
  std::string volumeMesh;
  BakeSpec spec = buildSpec(a, c, volumeMesh);
  if (!a.out.empty()) checkOutputFolder(a.out, "--out");
  const bool chatty = !a.json && !a.quiet;
  FarmClient client(connectionOf(a.conn));

  if (!a.scene.empty()) {
    std::optional<TemporaryScene> generated;
    std::string path = a.scene;
    if (isGeneratedScene(a.scene)) {
      generated.emplace(a.scene);
      path = generated->path();
      if (spec.sceneLights) {
        // The scene's lights go in the spec, first, as the local bake lists them.
        spec.lights = withSceneLights(generated->scene(), spec.lights, "--scene-lights: " + a.scene);
        spec.sceneLights = false;
      }
    }
    FarmClient::UploadResult up = client.uploadScene(path);
    if (up.alreadyThere)
      note(!chatty, "scene already on the server (" + up.sceneHash + ")");
    else
      note(!chatty, "uploaded " + a.scene + ": " + humanBytes(up.bytesSent) +
                        (up.resumedFrom ? " (resumed after " + humanBytes(up.resumedFrom) + ")" : "") + ", " +
                        std::to_string(up.triangles) + " triangles (" + up.sceneHash + ")");
    spec.sceneHash = up.sceneHash;
  }

  uploadReceiverVolume(client, volumeMesh, spec.options);
  const std::string requestId = a.requestId.empty() ? randomRequestId() : a.requestId;
  JobStatus status = client.submit(requestId, spec);
  if (!a.wait) {
    if (a.json)
      std::cout << statusJson(status, "", true) << "\n";
    else
      std::printf("%s\n", loggable(status.jobId).c_str());
    return 0;
  }

  note(!chatty, "job " + status.jobId + " submitted: " +
                    (status.grids ? std::to_string(status.lights) + " lights in " + std::to_string(status.grids) + " grids"
                                  : spec.resolution) +
                    ", " + std::to_string(status.tilesTotal) + " tiles");
  JobStatus final = followJob(client, status.jobId, chatty);
  std::string written;
  if (final.state == JobState::Done && !a.out.empty()) {
    client.download(final.jobId, a.out);
    written = a.out;
  }
  if (a.json) {
    std::cout << statusJson(final, "", true, written) << "\n";
  } else if (final.state == JobState::Done) {
    printDone(final);
    if (!written.empty()) std::printf("\nWrote %s\n", written.c_str());
  }
  return finalExitStatus(final);
}

// --- jobs, watch, cancel, download -------------------------------------------------------

struct JobsArgs {
  ConnectionArgs conn;
  bool all = false, json = false;
};

int runJobs(const JobsArgs& a) {
  FarmClient client(connectionOf(a.conn));
  std::vector<JobStatus> jobs = client.list(a.all);
  if (a.json) {
    std::cout << "{\"jobs\": [";
    for (size_t i = 0; i < jobs.size(); ++i) std::cout << (i ? ", " : "\n  ") << statusJson(jobs[i], "  ", false);
    std::cout << (jobs.empty() ? "]}\n" : "\n]}\n");
    return 0;
  }
  if (jobs.empty()) {
    std::fputs(a.all ? "no jobs\n" : "no unfinished jobs (--all lists finished ones too)\n", stdout);
    return 0;
  }
  int idWidth = 3;
  // What the coordinator sends reaches the terminal escaped (R26): names are free text.
  for (const auto& j : jobs) idWidth = std::max(idWidth, int(loggable(j.jobId).size()));
  std::printf("%-*s  %-9s  %13s  %10s  %8s  %s\n", idWidth, "JOB", "STATE", "TILES", "RESOLUTION", "ELAPSED", "NAME");
  for (const auto& j : jobs) {
    std::string tiles = std::to_string(j.tilesDone) + "/" + std::to_string(j.tilesTotal);
    std::printf("%-*s  %-9s  %13s  %10llu  %8s  %s\n", idWidth, loggable(j.jobId).c_str(), net::jobStateName(j.state),
                tiles.c_str(), static_cast<unsigned long long>(j.resolution), formatSeconds(j.secondsElapsed).c_str(),
                loggable(j.spec.name).c_str());
  }
  return 0;
}

struct WatchArgs {
  ConnectionArgs conn;
  std::string job;
  bool json = false, quiet = false;
};

int runWatch(const WatchArgs& a) {
  FarmClient client(connectionOf(a.conn));
  JobStatus final = followJob(client, a.job, !a.json && !a.quiet);
  if (a.json)
    std::cout << statusJson(final, "", true) << "\n";
  else if (final.state == JobState::Done)
    printDone(final);
  return finalExitStatus(final);
}

struct CancelArgs {
  ConnectionArgs conn;
  std::string job;
};

int runCancel(const CancelArgs& a) {
  FarmClient client(connectionOf(a.conn));
  JobStatus s = client.cancel(a.job);
  std::printf("%s\n", net::jobStateName(s.state));
  return 0;
}

struct DownloadArgs {
  ConnectionArgs conn;
  std::string job, out;
  bool quiet = false;
};

int runDownload(const DownloadArgs& a) {
  FarmClient client(connectionOf(a.conn));
  FarmClient::DownloadResult r = client.download(a.job, a.out);
  if (!a.quiet)
    std::printf("Wrote %s (%s%s, checksum %s verified)\n", a.out.c_str(), humanBytes(r.bytes).c_str(),
                r.resumedFrom ? (", resumed after " + humanBytes(r.resumedFrom)).c_str() : "", r.checksum.c_str());
  return 0;
}

}  // namespace

void addSubmitCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<SubmitArgs>();
  CLI::App* c = app.add_subcommand("submit", "Upload a scene to a bake farm and submit a bake of it");
  addConnectionOptions(c, a->conn);
  c->add_option("scene", a->scene,
                "Scene file (uploaded unless the server has it) or city[:BLOCKS[:SEED]]; optional when --job names a "
                "scene_hash");
  c->add_option("--job", a->jobFile, "Bake spec as JSON (BakeSpec); flags given here override its fields");
  addSunFlags(c, a->sun);
  c->add_option("--resolution,-r", a->resolution, "Grid resolution R (voxels a side): 1024, 4K, 16K, ... 1M")
      ->capture_default_str();
  addLightFlags(c, a->lights);
  c->add_option("--pointer-grid", a->pointerGrid,
                "Local lights: levels each grid's pointer grid answers in one read, 0 (none) to 5 (default)");
  c->add_option("--format", a->format,
                "cpvs (default) or dagmh: the sun's shadows as a DAG-MH (.dmh; as `cpvs bake --format dagmh`: "
                "cubic grids up to 64K, the raster renderer, no media)");
  addOptionFlags(c, a->options, "Tile size in texels (power of two >= 8): the unit of work of a worker");
  c->add_option("--request-id", a->requestId,
                "Idempotency key: submitting again with it returns the same job (default: a random id)");
  c->add_option("--priority", a->priority, "Higher runs first; equal priorities share the workers (-1000..1000)");
  c->add_option("--name", a->name, "Free text for listings (default: the scene's name)");
  CLI::Option* waitFlag = c->add_flag("--wait", a->wait, "Follow the job with a progress bar until it ends");
  c->add_option("--out,-o", a->out, "Download the artifact to this file (.cpvs, or .dmh for --format dagmh) once done")
      ->needs(waitFlag);
  c->add_flag("--json", a->json, "Print the job's status as JSON on stdout (the final one with --wait)");
  c->add_flag("--quiet,-q", a->quiet, "No progress output");
  c->callback([a, c, &status] { runFarmCommand(status, [&] { return runSubmit(*a, *c); }); });
}

void addJobsCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<JobsArgs>();
  CLI::App* c = app.add_subcommand("jobs", "List the jobs of a bake farm");
  addConnectionOptions(c, a->conn);
  c->add_flag("--all,-a", a->all, "Include finished jobs");
  c->add_flag("--json", a->json, "Print {\"jobs\": [status, ...]} as JSON on stdout");
  c->callback([a, &status] { runFarmCommand(status, [&] { return runJobs(*a); }); });
}

void addWatchCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<WatchArgs>();
  CLI::App* c = app.add_subcommand("watch", "Follow a farm job until it ends; exit 1 when it fails or is cancelled");
  addConnectionOptions(c, a->conn);
  c->add_option("job", a->job, "Job id")->required();
  c->add_flag("--json", a->json, "Print the final status as JSON on stdout");
  c->add_flag("--quiet,-q", a->quiet, "No progress output");
  c->callback([a, &status] { runFarmCommand(status, [&] { return runWatch(*a); }); });
}

void addCancelCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<CancelArgs>();
  CLI::App* c = app.add_subcommand("cancel", "Cancel a farm job; prints the state it is in afterwards");
  addConnectionOptions(c, a->conn);
  c->add_option("job", a->job, "Job id")->required();
  c->callback([a, &status] { runFarmCommand(status, [&] { return runCancel(*a); }); });
}

void addDownloadCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<DownloadArgs>();
  CLI::App* c = app.add_subcommand(
      "download", "Download the artifact (.cpvs or .dmh) of a finished farm job, resuming an interrupted download, "
                  "checksum verified");
  addConnectionOptions(c, a->conn);
  c->add_option("job", a->job, "Job id")->required();
  c->add_option("--out,-o", a->out, "Output .cpvs or .dmh file (FILE.part while it arrives)")->required();
  c->add_flag("--quiet,-q", a->quiet, "Print nothing on success");
  c->callback([a, &status] { runFarmCommand(status, [&] { return runDownload(*a); }); });
}

// --- sun tracks -----------------------------------------------------------------------

namespace {

struct TrackCreateArgs {
  ConnectionArgs conn;
  std::string scene, resolution = "4K", name, requestId, directions, start, end, up, north;
  OptionFlags options;
  double latitude = NAN, longitude = NAN, height = 0, step = 0, rate = 0;
  uint32_t ahead = 0, keep = 0;
  bool json = false;
};

std::string trackJson(const net::TrackStatus& t) {
  std::ostringstream o;
  o << "{\"track\": " << jsonString(t.trackId) << ", \"name\": " << jsonString(t.spec.name)
    << ", \"state\": " << jsonString(net::trackStateName(t.state)) << ", \"keyframes_total\": " << t.keyframesTotal
    << ", \"keyframes_published\": " << t.keyframesPublished << ", \"keyframes_skipped\": " << t.keyframesSkipped
    << ", \"latest_sequence\": " << t.latestSequence << ", \"error\": " << jsonString(t.error) << "}";
  return o.str();
}

int runTrackCreate(const TrackCreateArgs& a, const CLI::App& c) {
  auto given = [&](const char* option) { return c.count(option) > 0; };
  net::TrackSpec spec;
  spec.resolution = a.resolution;
  (void)parseResolution(a.resolution);
  const std::string volumeMesh = applyOptionFlags(a.options, c, spec.options);
  spec.name = a.name.empty() ? (isGeneratedScene(a.scene) ? a.scene : fs::path(a.scene).filename().string()) : a.name;
  spec.keyframesAhead = a.ahead;
  spec.keepVersions = a.keep;
  const bool place = given("--lat") || given("--lon") || given("--start");
  if (place == !a.directions.empty())
    throw InputError("give the sun path: --directions X,Y,Z;X,Y,Z;... or a place (--lat, --lon, --start, --step, and --end or --rate)");
  if (!a.directions.empty()) {
    std::stringstream list(a.directions);
    std::vector<Vec3> directions;
    for (std::string item; std::getline(list, item, ';');)
      if (!item.empty()) directions.push_back(parseVec3(item, "--directions"));
    spec.path = std::move(directions);
  } else {
    if (!given("--lat") || !given("--lon") || !given("--start") || !given("--step"))
      throw InputError("a place path needs --lat, --lon, --start and --step");
    if (given("--end") == given("--rate")) throw InputError("give --end (a span of time) or --rate (a game clock), not both");
    const net::PlacePath p{a.latitude, a.longitude, a.height, a.start, a.end, a.step, a.up, a.north};
    if (given("--rate"))
      spec.path = net::ClockPath{p, a.rate};
    else
      spec.path = p;
  }
  FarmClient client(connectionOf(a.conn));
  std::optional<TemporaryScene> generated;
  std::string path = a.scene;
  if (isGeneratedScene(a.scene)) {
    generated.emplace(a.scene);
    path = generated->path();
  }
  spec.sceneHash = client.uploadScene(path).sceneHash;
  uploadReceiverVolume(client, volumeMesh, spec.options);
  const net::TrackStatus t = client.createTrack(a.requestId.empty() ? randomRequestId() : a.requestId, spec);
  if (a.json) std::printf("%s\n", trackJson(t).c_str());
  else
    std::printf("%s  track of %s keyframes created; follow it: cpvs subscribe --server %s %s --out DIR\n",
                t.trackId.c_str(), t.keyframesTotal ? std::to_string(t.keyframesTotal).c_str() : "unbounded",
                a.conn.server.c_str(), t.trackId.c_str());
  return 0;
}

struct TrackListArgs {
  ConnectionArgs conn;
  bool all = false, json = false;
};

int runTrackList(const TrackListArgs& a) {
  FarmClient client(connectionOf(a.conn));
  const auto tracks = client.listTracks(a.all);
  if (a.json) {
    std::printf("[");
    for (size_t i = 0; i < tracks.size(); ++i) std::printf("%s\n  %s", i ? "," : "", trackJson(tracks[i]).c_str());
    std::printf("%s]\n", tracks.empty() ? "" : "\n");
    return 0;
  }
  std::printf("%-20s %-10s %-10s %-10s %s\n", "TRACK", "STATE", "PUBLISHED", "LATEST", "NAME");
  for (const auto& t : tracks)
    std::printf("%-20s %-10s %-10s %-10llu %s\n", t.trackId.c_str(), net::trackStateName(t.state),
                (std::to_string(t.keyframesPublished) + "/" +
                 (t.keyframesTotal ? std::to_string(t.keyframesTotal) : std::string("-")))
                    .c_str(),
                static_cast<unsigned long long>(t.latestSequence), loggable(t.spec.name, 80).c_str());
  return 0;
}

struct TrackCancelArgs {
  ConnectionArgs conn;
  std::string track;
};

int runTrackCancel(const TrackCancelArgs& a) {
  FarmClient client(connectionOf(a.conn));
  const net::TrackStatus t = client.cancelTrack(a.track);
  std::printf("%s\n", trackJson(t).c_str());
  return 0;
}

struct SubscribeArgs {
  ConnectionArgs conn;
  std::string track, out;
  uint64_t after = 0, count = 0;
  double giveUpSeconds = 300;
  bool quiet = false;
};

int runSubscribe(const SubscribeArgs& a) {
  if (!(a.giveUpSeconds >= 0)) throw InputError("--give-up must be 0 or more seconds");
  FarmClient client(connectionOf(a.conn));
  fs::create_directories(a.out);
  uint64_t received = 0, after = a.after;
  std::optional<std::chrono::steady_clock::time_point> lostSince;  // since when no version came
  double pause = 0.25;
  auto onVersion = [&](const net::TrackVersion& v, const std::vector<uint8_t>& bytes) {
    char name[64];
    std::snprintf(name, sizeof name, "version-%06llu.cpvs", static_cast<unsigned long long>(v.sequence));
    const std::string path = (fs::path(a.out) / name).string();
    writeFileAtomic(path, bytes);
    ++received;
    after = v.sequence;
    lostSince.reset();
    pause = 0.25;
    note(a.quiet, "version " + std::to_string(v.sequence) + " (keyframe " + std::to_string(v.keyframe) +
                      (v.instantUnixMs ? ", " + formatUtcInstant(utcFromUnixMillis(v.instantUnixMs)) : std::string()) +
                      ", " + humanBytes(bytes.size()) + ") -> " + path);
    return a.count == 0 || received < a.count;
  };
  // A lost connection (a coordinator restarting) is tried again with backoff, from the last
  // version written: no version is missed or written twice.
  while (true) {
    try {
      after = client.subscribe(a.track, after, onVersion);
      break;
    } catch (const FarmCallError& e) {
      if (e.kind() != net::ErrorKind::Unavailable) throw;
      if (!lostSince) lostSince = std::chrono::steady_clock::now();
      if (secondsSince(*lostSince) > a.giveUpSeconds) throw;
      note(a.quiet, std::string("connection lost (") + e.what() + "); trying again in " + std::to_string(int(pause * 1000)) +
                        " ms, after version " + std::to_string(after));
      std::this_thread::sleep_for(std::chrono::duration<double>(pause));
      pause = std::min(pause * 2, 8.0);
    }
  }
  note(a.quiet, "received " + std::to_string(received) + " version(s); resume after --after " + std::to_string(after));
  return 0;
}

}  // namespace

void addTrackCommand(CLI::App& app, int& status) {
  CLI::App* track = app.add_subcommand("track", "Sun tracks on a bake farm: keyframes baked ahead, published as versions");
  track->require_subcommand(1);
  auto a = std::make_shared<TrackCreateArgs>();
  CLI::App* c = track->add_subcommand("create", "Create a sun track of a scene (uploaded unless the server has it)");
  addConnectionOptions(c, a->conn);
  c->add_option("scene", a->scene, "Scene file or city[:BLOCKS[:SEED]]")->required();
  c->add_option("--resolution,-r", a->resolution, "Grid resolution of every keyframe")->capture_default_str();
  addOptionFlags(c, a->options, "Tile size in texels of every keyframe's job");
  c->add_option("--directions", a->directions, "A list of sun directions X,Y,Z;X,Y,Z;... (from the sun into the scene)");
  c->add_option("--lat", a->latitude, "A place: latitude, degrees north");
  c->add_option("--lon", a->longitude, "longitude, degrees east");
  c->add_option("--height", a->height, "height above the WGS84 ellipsoid, metres");
  c->add_option("--start", a->start, "The first keyframe's instant, ISO 8601 with a zone (a clock's time at creation)");
  c->add_option("--end", a->end, "The last instant of a span of time (inclusive)");
  c->add_option("--step", a->step, "Seconds between keyframes (of game time for a clock)");
  c->add_option("--rate", a->rate, "A game clock running RATE times real time (a 24-minute day: 60), never ending");
  c->add_option("--up", a->up, "The scene's up axis (default +Y)");
  c->add_option("--north", a->north, "The scene's north axis (default -Z)");
  c->add_option("--ahead", a->ahead, "Keyframes baked ahead of the last published (default 2)");
  c->add_option("--keep", a->keep, "Versions kept for subscribers (default 16)");
  c->add_option("--name", a->name, "Free text for listings (default: the scene's name)");
  c->add_option("--request-id", a->requestId, "Idempotency key: creating again with it returns the same track");
  c->add_flag("--json", a->json, "Print the track's status as JSON");
  c->callback([a, c, &status] { runFarmCommand(status, [&] { return runTrackCreate(*a, *c); }); });

  auto l = std::make_shared<TrackListArgs>();
  CLI::App* lc = track->add_subcommand("list", "The farm's active tracks (--all: ended ones too)");
  addConnectionOptions(lc, l->conn);
  lc->add_flag("--all", l->all, "Finished and cancelled tracks too");
  lc->add_flag("--json", l->json, "JSON: an array of {track, name, state, keyframes_total, keyframes_published, ...}");
  lc->callback([l, &status] { runFarmCommand(status, [&] { return runTrackList(*l); }); });

  auto x = std::make_shared<TrackCancelArgs>();
  CLI::App* xc = track->add_subcommand("cancel", "End a track; its keyframe jobs no other track needs are cancelled");
  addConnectionOptions(xc, x->conn);
  xc->add_option("track", x->track, "Track id")->required();
  xc->callback([x, &status] { runFarmCommand(status, [&] { return runTrackCancel(*x); }); });
}

void addSubscribeCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<SubscribeArgs>();
  CLI::App* c = app.add_subcommand(
      "subscribe", "Follow a sun track: write each version's .cpvs to DIR as it is published, until the track ends");
  addConnectionOptions(c, a->conn);
  c->add_option("track", a->track, "Track id")->required();
  c->add_option("--out,-o", a->out, "Folder for version-NNNNNN.cpvs")->required();
  c->add_option("--after", a->after, "The last version already held (resume token; default 0: from the oldest kept)");
  c->add_option("--count", a->count, "Stop after this many versions (default: until the track ends)");
  c->add_option("--give-up", a->giveUpSeconds,
                "Seconds without the coordinator before giving up (exit 4); until then a lost connection is tried "
                "again, backing off from 0.25 s to 8 s, from the last version written")
      ->capture_default_str();
  c->add_flag("--quiet,-q", a->quiet, "Print nothing but errors");
  c->callback([a, &status] { runFarmCommand(status, [&] { return runSubscribe(*a); }); });
}

}  // namespace cpvs::cli
