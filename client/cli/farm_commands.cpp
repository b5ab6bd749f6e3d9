// `cpvs submit | jobs | watch | cancel | download`: the bake farm from the command line.
// The transport is FarmClient; this file parses, prints and chooses exit statuses:
// 0 success, 1 the job failed or was cancelled, 2 bad input or a request the farm refused,
// 4 the farm could not be reached.
#include <algorithm>
#include <cctype>
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

#include "bake_flags.h"
#include "cli_util.h"
#include "commands.h"
#include "cpvs/base/error.h"
#include "cpvs/scene/import.h"
#include "cpvs/bake/stage_times.h"
#include "cpvs/scene/obj_writer.h"
#include "cpvs/base/parse.h"
#include "cpvs/base/text.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/light/frame.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/scene/source.h"
#include "cpvs/client/farm_client.h"
#include "cpvs/net/convert.h"

namespace cpvs::cli {

using client::FarmCallError;
using client::FarmClient;
using client::isFinalState;
using client::randomRequestId;
namespace pb = ::cpvs::v1;

namespace {

namespace fs = std::filesystem;

// --- shared -----------------------------------------------------------------------------

struct ConnectionArgs {
  std::string server, token, ca;
};

void addConnectionOptions(CLI::App* c, ConnectionArgs& a) {
  c->add_option("--server", a.server, "Coordinator HOST:PORT")->required();
  c->add_option("--token", a.token, "Bearer token (default: $CPVS_TOKEN)");
  c->add_option("--ca", a.ca, "PEM roots to trust: connect with TLS (plaintext without)");
}

net::Connection connectionOf(const ConnectionArgs& a) {
  net::Connection c{a.server, a.token, a.ca};
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

std::string formatSeconds(double s) {
  char buf[32];
  if (s < 60)
    std::snprintf(buf, sizeof buf, "%.1fs", s);
  else if (s < 3600)
    std::snprintf(buf, sizeof buf, "%dm%02ds", int(s) / 60, int(s) % 60);
  else
    std::snprintf(buf, sizeof buf, "%dh%02dm", int(s) / 3600, int(s) / 60 % 60);
  return buf;
}

/// Stage times summed by name, in the pipeline's order, then any others by name.
std::vector<std::pair<std::string, double>> stagesOf(const pb::JobStatus& s) {
  std::map<std::string, double> sum;
  for (const auto& st : s.stages()) sum[st.stage()] += st.seconds();
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
std::string statusJson(const pb::JobStatus& s, const std::string& indent, bool withOut, const std::string& out = {}) {
  const std::string in = indent + "  ";
  std::ostringstream o;
  o << "{\n"
    << in << "\"job\": " << jsonString(s.job_id()) << ",\n"
    << in << "\"request_id\": " << jsonString(s.request_id()) << ",\n"
    << in << "\"name\": " << jsonString(s.spec().name()) << ",\n"
    << in << "\"scene_hash\": " << jsonString(s.spec().scene_hash()) << ",\n"
    << in << "\"state\": " << jsonString(net::jobStateName(s.state())) << ",\n"
    << in << "\"priority\": " << s.spec().priority() << ",\n"
    << in << "\"resolution\": " << s.resolution() << ",\n"
    << in << "\"tiles\": " << s.tiles_total() << ",\n"
    << in << "\"tiles_done\": " << s.tiles_done() << ",\n"
    << in << "\"bytes\": " << s.bytes() << ",\n"
    << in << "\"file_bytes\": " << s.file_bytes() << ",\n"
    << in << "\"peak_merge_bytes\": " << s.peak_merge_bytes() << ",\n"
    << in << "\"seconds_total\": " << jsonNumber(s.seconds_elapsed()) << ",\n"
    << in << "\"eta_seconds\": " << (s.eta_seconds() < 0 ? "null" : jsonNumber(s.eta_seconds())) << ",\n"
    << in << "\"created_unix_ms\": " << s.created_unix_ms() << ",\n"
    << in << "\"stages\": {";
  bool first = true;
  for (const auto& [stage, seconds] : stagesOf(s)) {
    o << (first ? "" : ", ") << jsonString(stage) << ": " << jsonNumber(seconds);
    first = false;
  }
  o << "},\n" << in << "\"error\": " << jsonString(s.error());
  if (withOut) o << ",\n" << in << "\"out\": " << (out.empty() ? "null" : jsonString(out));
  o << "\n" << indent << "}";
  return o.str();
}

/// Follows a job to its end with a progress bar (stage = state, counts = tiles).
pb::JobStatus followJob(FarmClient& client, const std::string& jobId, bool show) {
  ProgressDisplay progress(show);
  pb::JobStatus final = client.watch(jobId, [&](const pb::JobStatus& s) {
    progress.update(net::jobStateName(s.state()), s.tiles_done(), s.tiles_total());
  });
  progress.finish();
  return final;
}

void printDone(const pb::JobStatus& s) {
  const uint64_t R = s.resolution();
  std::printf("Job %s done: %llu^3 in %llu tile%s, %.2f s\n", loggable(s.job_id()).c_str(), static_cast<unsigned long long>(R),
              static_cast<unsigned long long>(s.tiles_total()), s.tiles_total() == 1 ? "" : "s", s.seconds_elapsed());
  auto stages = stagesOf(s);
  if (!stages.empty()) {
    std::printf("\n  %-10s %10s\n", "stage", "seconds");
    for (const auto& [stage, seconds] : stages) std::printf("  %-10s %10.3f\n", stage.c_str(), seconds);
    std::printf("  (tile stages are summed over the workers)\n");
  }
  std::printf("\n  DAG: %s (%llu bytes), file: %s, largest merge held: %s\n", humanBytes(s.bytes()).c_str(),
              static_cast<unsigned long long>(s.bytes()), humanBytes(s.file_bytes()).c_str(),
              humanBytes(s.peak_merge_bytes()).c_str());
  if (R > 0 && s.bytes() > 0) {
    uint64_t sm = R * R * 2;
    std::printf("  16-bit shadow map of %llu^2: %s, %.1fx larger than the DAG\n", static_cast<unsigned long long>(R),
                humanBytes(sm).c_str(), double(sm) / double(s.bytes()));
  }
}

/// What a final status means for the exit status: 0 done, 1 failed or cancelled (with a
/// message on stderr).
int finalExitStatus(const pb::JobStatus& s) {
  if (s.state() == pb::JOB_FAILED) {
    std::fprintf(stderr, "cpvs: job %s failed: %s\n", loggable(s.job_id()).c_str(), loggable(s.error(), 2000).c_str());
    return 1;
  }
  if (s.state() == pb::JOB_CANCELLED) {
    std::fprintf(stderr, "cpvs: job %s was cancelled\n", loggable(s.job_id()).c_str());
    return 1;
  }
  return 0;
}

// --- submit -----------------------------------------------------------------------------

struct SubmitArgs {
  ConnectionArgs conn;
  std::string scene, jobFile, requestId, name, out;
  std::string resolution = "4K";
  SunFlags sun;
  OptionFlags options;
  int priority = 0;
  bool wait = false, json = false, quiet = false;
};

bool isGeneratedScene(const std::string& scene) { return scene == "city" || scene.starts_with("city:"); }

/// A generated scene written to a temporary OBJ file (positions with full double
/// precision), removed with its folder when this goes out of scope.
class TemporaryScene {
 public:
  explicit TemporaryScene(const std::string& spec) {
    Scene scene = openScene(spec);
    std::string pattern = (fs::temp_directory_path() / "cpvs-scene-XXXXXX").string();
    if (!::mkdtemp(pattern.data())) throw InputError("cannot create a temporary folder: " + std::string(std::strerror(errno)));
    dir_ = pattern;
    std::string base = spec;
    for (char& ch : base)
      if (ch == ':') ch = '-';
    path_ = (fs::path(dir_) / (base + ".obj")).string();
    writeObj(path_, scene, spec + ", generated by cpvs");
  }
  ~TemporaryScene() {
    std::error_code ignored;
    fs::remove_all(dir_, ignored);
  }
  TemporaryScene(const TemporaryScene&) = delete;
  TemporaryScene& operator=(const TemporaryScene&) = delete;

  const std::string& path() const { return path_; }

 private:
  std::string dir_, path_;
};

/// The spec to submit: the job file's, if any, with every flag given on the command line
/// overriding its field, and the bake defaults for what neither gives. Validated here,
/// before anything is uploaded; InputError names the flag or field.
pb::BakeSpec buildSpec(const SubmitArgs& a, const CLI::App& c) {
  auto given = [&](const char* option) { return c.count(option) > 0; };
  pb::BakeSpec spec;
  if (!a.jobFile.empty()) {
    std::vector<uint8_t> bytes = readFile(a.jobFile);
    spec = net::specFromJson(std::string(bytes.begin(), bytes.end()), a.jobFile);
  }

  const bool dir = given("--sun-dir"), elevation = given("--sun-elevation"), azimuth = given("--sun-azimuth");
  if (dir && (elevation || azimuth))
    throw InputError("give either --sun-dir or --sun-elevation/--sun-azimuth, not both");
  if (dir) {
    *spec.mutable_sun_direction() = net::toProto(parseVec3(a.sun.dir, "--sun-dir"));
  } else if (elevation || azimuth) {
    if (!elevation && spec.sun_case() != pb::BakeSpec::kSunAngles)
      throw InputError("--sun-azimuth needs --sun-elevation (or sun_angles in the job file)");
    pb::SunAngles angles = spec.sun_case() == pb::BakeSpec::kSunAngles ? spec.sun_angles() : pb::SunAngles();
    if (elevation) angles.set_elevation_deg(a.sun.elevation);
    if (azimuth) angles.set_azimuth_deg(a.sun.azimuth);
    *spec.mutable_sun_angles() = angles;
  }
  if (spec.sun_case() == pb::BakeSpec::SUN_NOT_SET)
    throw InputError(std::string("give the light: --sun-dir X,Y,Z or --sun-elevation DEG") +
                     (a.jobFile.empty() ? "" : " (or sun_direction or sun_angles in " + a.jobFile + ")"));
  (void)net::lightOf(spec);

  if (given("--resolution") || spec.resolution().empty()) spec.set_resolution(a.resolution);
  (void)parseResolution(spec.resolution());

  pb::BakeOptions& o = *spec.mutable_options();
  // Each flag given overrides its field; the proto's enum values are the core's
  // (static_asserts in net/src/convert.cpp).
  const BakeOptions flags = optionsOf(a.options);
  if (given("--closed")) o.set_closed(pb::ClosedMode(flags.closed));
  if (given("--exit")) o.set_exit(pb::ExitMode(flags.exit));
  if (given("--cull")) o.set_no_cull(!flags.cull);
  if (given("--compress")) o.set_compress(pb::CompressMode(flags.compress));
  if (given("--undefined")) o.set_undefined_rule(pb::UndefinedRule(flags.undefinedRule));
  if (given("--tile-size")) o.set_tile_size(uint32_t(1) << flags.log2TileSize);
  if (given("--renderer")) o.set_renderer(pb::Renderer(flags.renderer));
  (void)net::fromProto(o);

  if (given("--priority")) spec.set_priority(a.priority);
  if (given("--name")) spec.set_name(a.name);
  if (spec.name().empty() && !a.scene.empty())
    spec.set_name(isGeneratedScene(a.scene) ? a.scene : fs::path(a.scene).filename().string());
  if (a.scene.empty() && spec.scene_hash().empty())
    throw InputError("give the SCENE to bake (a file or city[:BLOCKS[:SEED]]), or a scene_hash in the job file");
  return spec;
}

int runSubmit(const SubmitArgs& a, const CLI::App& c) {
  pb::BakeSpec spec = buildSpec(a, c);
  const bool chatty = !a.json && !a.quiet;
  FarmClient client(connectionOf(a.conn));

  if (!a.scene.empty()) {
    std::optional<TemporaryScene> generated;
    std::string path = a.scene;
    if (isGeneratedScene(a.scene)) {
      generated.emplace(a.scene);
      path = generated->path();
    }
    FarmClient::UploadResult up = client.uploadScene(path);
    if (up.alreadyThere)
      note(!chatty, "scene already on the server (" + up.sceneHash + ")");
    else
      note(!chatty, "uploaded " + a.scene + ": " + humanBytes(up.bytesSent) +
                        (up.resumedFrom ? " (resumed after " + humanBytes(up.resumedFrom) + ")" : "") + ", " +
                        std::to_string(up.triangles) + " triangles (" + up.sceneHash + ")");
    spec.set_scene_hash(up.sceneHash);
  }

  const std::string requestId = a.requestId.empty() ? randomRequestId() : a.requestId;
  pb::JobStatus status = client.submit(requestId, spec);
  if (!a.wait) {
    if (a.json)
      std::cout << statusJson(status, "", true) << "\n";
    else
      std::printf("%s\n", loggable(status.job_id()).c_str());
    return 0;
  }

  note(!chatty, "job " + status.job_id() + " submitted: " + spec.resolution() + ", " +
                    std::to_string(status.tiles_total()) + " tiles");
  pb::JobStatus final = followJob(client, status.job_id(), chatty);
  std::string written;
  if (final.state() == pb::JOB_DONE && !a.out.empty()) {
    client.download(final.job_id(), a.out);
    written = a.out;
  }
  if (a.json) {
    std::cout << statusJson(final, "", true, written) << "\n";
  } else if (final.state() == pb::JOB_DONE) {
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
  std::vector<pb::JobStatus> jobs = client.list(a.all);
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
  for (const auto& j : jobs) idWidth = std::max(idWidth, int(loggable(j.job_id()).size()));
  std::printf("%-*s  %-9s  %13s  %10s  %8s  %s\n", idWidth, "JOB", "STATE", "TILES", "RESOLUTION", "ELAPSED", "NAME");
  for (const auto& j : jobs) {
    std::string tiles = std::to_string(j.tiles_done()) + "/" + std::to_string(j.tiles_total());
    std::printf("%-*s  %-9s  %13s  %10llu  %8s  %s\n", idWidth, loggable(j.job_id()).c_str(), net::jobStateName(j.state()),
                tiles.c_str(), static_cast<unsigned long long>(j.resolution()),
                formatSeconds(j.seconds_elapsed()).c_str(), loggable(j.spec().name()).c_str());
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
  pb::JobStatus final = followJob(client, a.job, !a.json && !a.quiet);
  if (a.json)
    std::cout << statusJson(final, "", true) << "\n";
  else if (final.state() == pb::JOB_DONE)
    printDone(final);
  return finalExitStatus(final);
}

struct CancelArgs {
  ConnectionArgs conn;
  std::string job;
};

int runCancel(const CancelArgs& a) {
  FarmClient client(connectionOf(a.conn));
  pb::JobStatus s = client.cancel(a.job);
  std::printf("%s\n", net::jobStateName(s.state()));
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
  addOptionFlags(c, a->options, "Tile size in texels (power of two >= 8): the unit of work of a worker");
  c->add_option("--request-id", a->requestId,
                "Idempotency key: submitting again with it returns the same job (default: a random id)");
  c->add_option("--priority", a->priority, "Higher runs first; equal priorities share the workers (-1000..1000)");
  c->add_option("--name", a->name, "Free text for listings (default: the scene's name)");
  CLI::Option* waitFlag = c->add_flag("--wait", a->wait, "Follow the job with a progress bar until it ends");
  c->add_option("--out,-o", a->out, "Download the artifact to this .cpvs file once done")->needs(waitFlag);
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
      "download", "Download the .cpvs of a finished farm job, resuming an interrupted download, checksum verified");
  addConnectionOptions(c, a->conn);
  c->add_option("job", a->job, "Job id")->required();
  c->add_option("--out,-o", a->out, "Output .cpvs file (FILE.part while it arrives)")->required();
  c->add_flag("--quiet,-q", a->quiet, "Print nothing on success");
  c->callback([a, &status] { runFarmCommand(status, [&] { return runDownload(*a); }); });
}

}  // namespace cpvs::cli
