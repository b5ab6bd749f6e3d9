// The farm's requests and answers as plain values: what a client submits and what it is
// told, field for field the contract's messages (proto/cpvs/v1/farm.proto) with the core's
// enums, vectors and lights. The client library's API, the command line and the job
// service speak these; protobuf stays at the wire, behind model_convert.h.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/base/vec3.h"
#include "cpvs/light/area_light.h"
#include "cpvs/light/frame.h"
#include "cpvs/light/light.h"

namespace cpvs::net {

struct Box {
  Vec3 min, max;
  bool operator==(const Box&) const = default;
};

/// Which points a bake's lookups may read, beyond the kind: a declared volume, the places
/// cameras can be and how far they see, a layer above walkable ground (contract: Receivers).
struct Receivers {
  ReceiverKind kind = ReceiverKind::Everywhere;
  uint32_t maxPcf = 0;  // the widest PCF filter of the lookups; 0: 9
  std::string volumeSceneHash;  // an uploaded closed mesh (Volume, optionally Cameras)
  std::vector<Box> boxes;
  std::vector<Box> cameraRegions;
  double viewDistance = 0;
  std::vector<Vec3> cameraPoints;
  std::vector<std::vector<Vec3>> cameraPaths;  // polylines of one point or more
  CameraVisibility cameraVisibility = CameraVisibility::Faced;
  double cameraSpacing = 0;  // Sampled: 0 is a sixteenth of the view distance
  uint32_t cameraRays = 0;   // Sampled: 0 is kDefaultCameraRays
  double groundLayer = 0;    // scene units above walkable ground; 0: none
  std::optional<double> groundSlopeDeg;  // absent: 45
  double groundLayerFrom = 0;
  bool operator==(const Receivers&) const = default;
};

/// The options of a job as submitted (contract: BakeOptions). The defaults are the bake's;
/// bakeOptionsOf checks them and gives the core's BakeOptions.
struct JobOptions {
  ClosedMode closed = ClosedMode::Auto;
  ExitMode exit = ExitMode::Exact;
  bool cull = true;
  CompressMode compress = CompressMode::TopDown;
  UndefinedRule undefinedRule = UndefinedRule::Aligned;  // always on the wire (absent there: new)
  uint32_t tileSize = 0;              // texels a side; 0: 4096
  uint32_t depthSlices = 0;           // slices across the scene's depth; 0: the resolution
  std::optional<Renderer> renderer;   // absent: the bake's default (raster)
  std::optional<Receivers> receivers; // absent: everywhere
  bool operator==(const JobOptions&) const = default;
};

struct SunAngles {
  double elevationDeg = 0;
  double azimuthDeg = 0;
  bool operator==(const SunAngles&) const = default;
};

/// A participating medium a bake is declared for, by name (contract: Medium).
struct MediumSpec {
  std::string name;
  double scattering = 0, absorption = 0, g = 0;
  bool operator==(const MediumSpec&) const = default;
};

/// What a job bakes (contract: BakeSpec): a sun (a direction from the sun into the scene,
/// or angles) at a resolution, or a light bundle (lights, area lights, the scene's own).
/// What a sun bake makes (contract: ArtifactFormat).
enum class ArtifactFormat : uint8_t { Cpvs = 0, DagMh = 1 };
/// "cpvs" or "dagmh", as `cpvs bake --format` names them.
const char* formatName(ArtifactFormat f);
/// The format a name gives; InputError naming `what` for another.
ArtifactFormat parseFormat(const std::string& name, const std::string& what);

struct BakeSpec {
  std::string sceneHash;  // an uploaded scene's content hash, 32 hex digits
  std::variant<std::monostate, Vec3, SunAngles> sun;
  std::string resolution;  // "4096", "4K", ...; "" for a light bundle
  JobOptions options;
  int32_t priority = 0;    // higher first
  std::string name;        // free text for listings
  std::vector<Light> lights;
  bool sceneLights = false;
  double footprint = 0;    // 0: the scene's diagonal / 4096
  std::optional<uint32_t> pointerGrid;
  std::vector<MediumSpec> media;
  std::vector<AreaLight> areaLights;
  ArtifactFormat format = ArtifactFormat::Cpvs;
};

/// Whether the spec asks for a light bundle (lights, area lights or the scene's own) rather
/// than a sun.
bool isLightBundle(const BakeSpec& spec);
/// The sun of a sun bake's spec: InputError unless it names a finite non-zero direction
/// or a sun above the horizon.
LightFrame lightOf(const BakeSpec& spec);

enum class JobState : uint8_t { Unspecified = 0, Queued = 1, Running = 2, Merging = 3, Done = 4, Failed = 5, Cancelled = 6 };

/// "queued", "running", ... ("unknown" for a value out of range).
const char* jobStateName(JobState s);
/// True for the states a job never leaves: Done, Failed, Cancelled.
bool isFinalState(JobState s);

struct StageSeconds {
  std::string stage;
  double seconds = 0;
};

/// A job as the coordinator reports it (contract: JobStatus).
struct JobStatus {
  std::string jobId, requestId;
  JobState state = JobState::Unspecified;
  BakeSpec spec;
  uint64_t tilesTotal = 0, tilesDone = 0;
  uint64_t tilesUntouched = 0;  // of tilesDone, those no triangle touches (never leased)
  uint64_t tilesUnread = 0;     // of tilesDone, those no declared receiver reads (never leased)
  uint64_t tilesReused = 0;     // of tilesDone, those a worker sent from its tile cache (not baked)
  std::vector<StageSeconds> stages;  // summed over tiles, plus the coordinator's merge and write
  double secondsElapsed = 0;
  double etaSeconds = -1;       // < 0: unknown
  std::string error;
  uint64_t bytes = 0;           // DAG bytes once done
  uint64_t fileBytes = 0;       // artifact file size once done
  uint64_t resolution = 0;      // a bundle's finest grid's
  uint64_t peakMergeBytes = 0;
  int64_t createdUnixMs = 0;
  uint32_t lights = 0, grids = 0;  // a light bundle's (0: a sun bake)
};

/// A place on Earth and a span of time (or a clock's start) the sun is followed over
/// (contract: PlacePath).
struct PlacePath {
  double latitudeDeg = 0, longitudeDeg = 0, heightM = 0;
  std::string startUtc, endUtc;  // ISO 8601 with a zone; endUtc inclusive, "" for a clock
  double stepSeconds = 0;
  std::string up, north;         // the scene's up and north axes; "": the defaults
  bool operator==(const PlacePath&) const = default;
};

/// A game clock: the place's sun from its start at `rate` game seconds a second.
struct ClockPath {
  PlacePath place;
  double rate = 0;
  bool operator==(const ClockPath&) const = default;
};

/// A sun track (contract: TrackSpec): keyframes along a path, each a sun bake.
struct TrackSpec {
  std::string sceneHash, resolution;
  JobOptions options;
  std::string name;
  std::variant<std::monostate, PlacePath, std::vector<Vec3>, ClockPath> path;  // vector: sun directions
  uint32_t keyframesAhead = 0;  // 0: 2
  uint32_t keepVersions = 0;    // 0: 16
};

enum class TrackState : uint8_t { Unspecified = 0, Active = 1, Finished = 2, Cancelled = 3 };

/// "active", "finished", "cancelled" ("unknown" otherwise).
const char* trackStateName(TrackState s);

struct TrackStatus {
  std::string trackId, requestId;
  TrackState state = TrackState::Unspecified;
  TrackSpec spec;
  uint64_t keyframesTotal = 0;  // 0 for a clock
  uint64_t keyframesPublished = 0, keyframesSkipped = 0;
  uint64_t latestSequence = 0;
  std::string error;
  int64_t createdUnixMs = 0;
};

/// One published version of a track: its keyframe's sun and artifact.
struct TrackVersion {
  std::string trackId;
  uint64_t sequence = 0;      // 1, 2, ...: a subscriber's resume token
  uint64_t keyframe = 0;
  int64_t instantUnixMs = 0;  // 0 for direction lists
  Vec3 sunDirection;
  std::string jobId;
  std::string checksum;       // XXH3-128 of the artifact, 32 hex digits
  uint64_t fileBytes = 0;
};

/// The core's options of a job's: InputError naming the field for an unknown value or a
/// tile size that is no power of two in range (the receivers' volume and cameras are the
/// declaration's, net/receiver_declaration.h).
BakeOptions bakeOptionsOf(const JobOptions& options);

/// A job file (the JSON form of BakeSpec, field names as the contract's) and back.
/// InputError naming `source` for anything malformed or unknown.
BakeSpec bakeSpecFromJson(const std::string& json, const std::string& source);
std::string toJson(const BakeSpec& spec);

/// A lights file (the JSON form of a list of lights): InputError naming the file for
/// anything unreadable, malformed or not a light field, or a light count outside
/// [1, kMaxLights].
std::vector<Light> readLightsFile(const std::string& path);

}  // namespace cpvs::net
