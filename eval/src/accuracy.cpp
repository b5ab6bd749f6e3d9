#include "cpvs/eval/accuracy.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

#include "cpvs/io/cpvs_file.h"
#include "cpvs/query/dag_mh_query.h"
#include "cpvs/query/shadow_query.h"
#include "cpvs/bake/bake_dag_mh.h"
#include "cpvs/eval/shadow_map.h"
#include "cpvs/eval/verify.h"
#include "cpvs/raytrace/visibility.h"

namespace cpvs {

int distanceBin(double distance, double texel) {
  const double t = distance / texel;
  // Radii are powers of two times texel / 16, so they land exactly on the bin edges; a
  // hair of tolerance keeps rounding in the division from moving one up a bin.
  const double tol = 1e-9;
  if (t <= 1 + tol) return 0;
  if (t <= 2 + tol) return 1;
  if (t <= 4 + tol) return 2;
  if (t <= 8 + tol) return 3;
  return 4;
}

double boundaryDistance(const RayScene& rays, const OrthoGrid& grid, const Vec3& q, const Vec3& n, bool lit, double r0,
                        double rMax) {
  const Vec3& dir = grid.frame.dir;
  const double nl = length(n);
  const double cosL = nl > 0 ? dot(n, dir) / nl : 0.0;
  const bool follow = std::abs(cosL) >= kFollowReceiverMinCos;
  // Offsets per unit radius: across the light (sliding along it to stay on the receiver's
  // plane), then towards the light.
  std::array<Vec3, kBoundaryProbeDirections> steps;
  for (int k = 0; k < 12; ++k) {
    const double a = k * std::numbers::pi / 6.0;
    const Vec3 across = grid.frame.u * std::cos(a) + grid.frame.v * std::sin(a);
    steps[k] = follow ? across - dir * (dot(across, n) / nl / cosL) : across;
  }
  steps[12] = -dir;
  for (double r = r0; r <= rMax * (1 + 1e-12); r *= 2)
    for (const Vec3& d : steps)
      if (exactlyLit(rays, grid, q + d * r) != lit) return r;
  return std::numeric_limits<double>::infinity();
}

double exactFootprintLit(const RayScene& rays, const OrthoGrid& grid, uint32_t side, const Vec3& q, int pcf,
                         int perTexel) {
  // Points spread evenly over each texel of the footprint, at q's own depth.
  const OrthoGrid cells = grid.withSide(side);
  const Vec3 qv = cells.voxelFromWorld(q);
  const double tx = std::floor(qv.x), ty = std::floor(qv.y);
  const int r = pcf / 2, k = std::max(1, perTexel);
  int lit = 0;
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx)
      for (int b = 0; b < k; ++b)
        for (int a = 0; a < k; ++a)
          lit += exactlyLit(rays, grid, cells.worldFromVoxel({tx + dx + (a + 0.5) / k, ty + dy + (b + 0.5) / k, qv.z}));
  return double(lit) / double(pcf * pcf * k * k);
}

const char* accuracyMethodName(AccuracyMethod m) {
  switch (m) {
    case AccuracyMethod::Cpvs: return "CPVS";
    case AccuracyMethod::ShadowMapEqualBytes: return "shadow map, equal bytes";
    case AccuracyMethod::ShadowMapEqualBytesCpvsOffset: return "shadow map, equal bytes, CPVS offset";
    case AccuracyMethod::ShadowMapFull: return "shadow map, full resolution";
    case AccuracyMethod::DagMh: return "DAG-MH";
    case AccuracyMethod::FloatMapFull: return "float map, full resolution";
    case AccuracyMethod::CpvsEverywhere: return "CPVS, receivers everywhere";
  }
  return "?";
}

const char* accuracyMethodKey(AccuracyMethod m) {
  switch (m) {
    case AccuracyMethod::Cpvs: return "cpvs";
    case AccuracyMethod::ShadowMapEqualBytes: return "sm_equal_bytes";
    case AccuracyMethod::ShadowMapEqualBytesCpvsOffset: return "sm_equal_bytes_cpvs_offset";
    case AccuracyMethod::ShadowMapFull: return "sm_full";
    case AccuracyMethod::DagMh: return "dagmh";
    case AccuracyMethod::FloatMapFull: return "float_full";
    case AccuracyMethod::CpvsEverywhere: return "cpvs_everywhere";
  }
  return "?";
}

std::string resolutionLabel(uint64_t r) {
  return r >= 1024 && r % 1024 == 0 ? std::to_string(r / 1024) + "K" : std::to_string(r);
}

double AccuracyRow::binRate(int bin) const {
  return binSamples[bin] ? double(binMismatches[bin]) / double(binSamples[bin]) : std::nan("");
}

namespace {

// The samples' query points for one offset rule and what exact rays say about them.
struct QueryPoints {
  std::vector<Vec3> points;
  std::vector<uint8_t> inside, lit;
  std::vector<double> distance;
};

class Reporter {
 public:
  explicit Reporter(const ProgressFn& fn) : fn_(fn) {}
  void operator()(const std::string& stage, uint64_t done, uint64_t total) const {
    if (fn_ && !fn_({stage, done, total})) throw Cancelled();
  }
  const ProgressFn& fn() const { return fn_; }

 private:
  const ProgressFn& fn_;
};

// Runs body(i) for i in [0, n) in parallel, in chunks so that progress is reported from
// the calling thread between them.
template <class Body>
void forChunks(size_t n, const std::string& stage, const Reporter& report, Body&& body) {
  constexpr size_t kChunk = 8192;
  report(stage, 0, n);
  for (size_t b = 0; b < n; b += kChunk) {
    const size_t e = std::min(n, b + kChunk);
    tbb::parallel_for(tbb::blocked_range<size_t>(b, e, 64), [&](const auto& range) {
      for (size_t i = range.begin(); i != range.end(); ++i) body(i);
    });
    report(stage, e, n);
  }
}

void tally(AccuracyRow& row, const QueryPoints& qp, const std::vector<uint8_t>& answerLit, double texel) {
  for (size_t i = 0; i < qp.points.size(); ++i) {
    if (qp.inside[i]) {
      ++row.skippedInside;
      continue;
    }
    const int bin = distanceBin(qp.distance[i], texel);
    const bool bad = answerLit[i] != qp.lit[i];
    ++row.samples;
    ++row.binSamples[bin];
    row.mismatches += bad;
    row.binMismatches[bin] += bad;
  }
}

// |lookup - exact| where the lookup is a float count / (w^2) and the exact fraction a count
// / (w^2 k^2): snapped to a multiple of 1 / (w^2 k^2) so that float rounding reads as 0.
double pcfError(double lookup, double exact, int pcf, int perTexel) {
  const double d = double(pcf * pcf * perTexel * perTexel);
  return std::round(std::abs(lookup - exact) * d) / d;
}

void summarize(PcfAccuracy& out, int width, std::vector<double>& errors) {
  out.width = width;
  out.samples = errors.size();
  if (errors.empty()) return;
  double sum = 0;
  for (double e : errors) sum += e;
  out.meanAbsError = sum / double(errors.size());
  const size_t k = size_t(std::ceil(0.99 * double(errors.size()))) - 1;
  std::nth_element(errors.begin(), errors.begin() + k, errors.end());
  out.p99AbsError = errors[k];
}

// Nanoseconds per query of a batched lookup over n points: one warm-up call, then repeats
// until at least minSeconds have passed.
template <class Fn>
double nsPerQuery(size_t n, double minSeconds, Fn&& fn) {
  if (n == 0) return 0;
  fn();
  uint64_t reps = 0;
  const auto start = std::chrono::steady_clock::now();
  double s = 0;
  do {
    fn();
    ++reps;
    s = secondsSince(start);
  } while (s < minSeconds);
  return s / double(reps) / double(n) * 1e9;
}

// What every resolution shares: the scene's BVH, the sample points and their normals.
struct Inputs {
  const Scene& scene;
  const LightFrame& frame;
  const AccuracyOptions& options;
  const ProgressFn& progress;
  const Reporter& report;
  const RayScene& rays;
  std::vector<Vec3> points, normals;
  double shadowRay = 0;  // shadowRayLength of the grid
  Hash128 geometryHash;
  double firstRadius = 0, maxRadius = 0;
  size_t pcfSamples = 0;
  size_t count() const { return points.size(); }
};

// The methods measured at one resolution: the CPVS and the shadow maps, with their rows.
struct Methods {
  ShadowQuery query;
  ShadowMap equalBytes, fullMap, floatMap;
  bool full = false, fullFloat = false;
  uint32_t equalSide = 0;
  AccuracyRow cpvs, eq, eqOff, fullRow;
  std::optional<DagMhQuery> dagMh;  // the same receivers' DAG-MH, looked up at the CPVS's offset point
  AccuracyRow dagMhRow, floatRow;
  std::optional<ShadowQuery> everywhere;  // the CPVS for receivers everywhere, when others are declared
  AccuracyRow everywhereRow;
};

// The DAG-MH of the same receivers at this resolution, timed; its row filled in.
void dagMhRow(const Inputs& in, const OrthoGrid& grid, const std::string& label, Methods& m) {
  AccuracyRow& row = m.dagMhRow;
  row.method = AccuracyMethod::DagMh;
  row.log2Resolution = grid.log2Resolution;
  row.side = grid.resolution();
  BakeOptions options = in.options.bake;
  options.receivers = in.options.receivers.kind;
  options.receiverPcf = uint8_t(in.options.receivers.maxPcf);
  StageTimes st;
  const auto start = std::chrono::steady_clock::now();
  try {
    DagMh dag = bakeDagMh(in.scene, grid, options, in.options.receivers, 0, &st, [&](const Progress& p) {
      return !in.progress || in.progress({label + " DAG-MH", p.done, p.total, p.secondsLeft});
    });
    row.bakeSeconds = secondsSince(start);
    row.stageSeconds = st.seconds;
    row.bytes = dag.bytes();
    m.dagMh.emplace(grid, std::move(dag));
  } catch (const InputError& e) {  // beyond what a DAG-MH holds: the row says why
    row.skipped = true;
    row.note = std::string("skipped: ") + e.what();
  }
}

// The CPVS at this resolution for `receivers`, timed per stage; its row's size and times
// filled in.
ShadowQuery bakeRow(const Inputs& in, const OrthoGrid& grid, const std::string& label, const ReceiverDeclaration& receivers,
                    AccuracyRow& row) {
  row.log2Resolution = grid.log2Resolution;
  row.side = grid.resolution();
  CpvsArtifact art;
  art.grid = grid;
  art.options = in.options.bake;
  art.sceneHash = in.geometryHash;
  art.options.receivers = receivers.kind;
  art.options.receiverPcf = uint8_t(receivers.maxPcf);
  StageTimes st;
  const auto start = std::chrono::steady_clock::now();
  // The bake's own renderer, as `cpvs bake` would prepare it (included in the bake time).
  const BakeScene prepared(in.scene, grid, in.options.bake.renderer, 0, receivers);
  art.dag = bakeGrid(prepared, art.options, &st, [&](const Progress& p) {
    return !in.progress || in.progress({label + " bake", p.done, p.total, p.secondsLeft});
  });
  row.bakeSeconds = secondsSince(start);
  row.stageSeconds = st.seconds;
  row.bytes = art.dag.bytes();
  return ShadowQuery(art.grid, PackedDag(art.dag));
}

// The CPVS for receivers everywhere beside one for declared receivers (the first's bytes
// are what the declaration saves); skipped when the declaration is everywhere.
void everywhereRow(const Inputs& in, const OrthoGrid& grid, const std::string& label, Methods& m) {
  AccuracyRow& row = m.everywhereRow;
  row.method = AccuracyMethod::CpvsEverywhere;
  row.log2Resolution = grid.log2Resolution;
  row.side = grid.resolution();
  if (in.options.receivers.kind == ReceiverKind::Everywhere) {
    row.skipped = true;
    row.bytes = m.cpvs.bytes;
    row.note = "the CPVS row is the bake for receivers everywhere";
    return;
  }
  m.everywhere.emplace(bakeRow(in, grid, label + " everywhere", ReceiverDeclaration{}, row));
}

// The shadow maps: one with the DAG's bytes, one 16-bit and one float with the CPVS's
// texels (when not over the size limit), and their rows.
void baselineRows(const Inputs& in, const OrthoGrid& grid, const std::string& label, Methods& m) {
  const uint64_t R = grid.resolution();
  m.full = R * R * 2 <= in.options.maxFullShadowMapBytes;
  m.fullFloat = R * R * 4 <= in.options.maxFullShadowMapBytes;
  in.report(label + " shadow maps", 0, m.full ? 2 : 1);
  m.equalSide = uint32_t(std::max<double>(1.0, std::floor(std::sqrt(double(m.cpvs.bytes) / 2.0))));
  m.eq.method = AccuracyMethod::ShadowMapEqualBytes;
  m.eqOff.method = AccuracyMethod::ShadowMapEqualBytesCpvsOffset;
  m.fullRow.method = AccuracyMethod::ShadowMapFull;
  for (AccuracyRow* r : {&m.eq, &m.eqOff, &m.fullRow}) r->log2Resolution = grid.log2Resolution;
  auto start = std::chrono::steady_clock::now();
  m.equalBytes = renderShadowMap(in.rays, grid, m.equalSide);
  m.eq.bakeSeconds = m.eqOff.bakeSeconds = secondsSince(start);
  m.eq.side = m.eqOff.side = m.equalSide;
  m.eq.bytes = m.eqOff.bytes = m.equalBytes.bytes();
  m.eqOff.note = "the map above, looked up at the CPVS's offset point";
  in.report(label + " shadow maps", 1, m.full ? 2 : 1);
  m.fullRow.side = R;
  m.fullRow.bytes = R * R * 2;
  if (m.full) {
    start = std::chrono::steady_clock::now();
    m.fullMap = renderShadowMap(in.rays, grid, uint32_t(R));
    m.fullRow.bakeSeconds = secondsSince(start);
    in.report(label + " shadow maps", 2, 2);
  } else {
    m.fullRow.skipped = true;
    m.fullRow.note = "skipped: " + std::to_string(R * R * 2) + " bytes is over the limit of " +
                     std::to_string(in.options.maxFullShadowMapBytes);
  }
  AccuracyRow& f = m.floatRow;
  f.method = AccuracyMethod::FloatMapFull;
  f.log2Resolution = grid.log2Resolution;
  f.side = R;
  f.bytes = R * R * 4;
  if (m.fullFloat) {
    start = std::chrono::steady_clock::now();
    m.floatMap = renderShadowMap(in.rays, grid, uint32_t(R), true);
    f.bakeSeconds = secondsSince(start);
  } else {
    f.skipped = true;
    f.note = "skipped: " + std::to_string(R * R * 4) + " bytes is over the limit of " +
             std::to_string(in.options.maxFullShadowMapBytes);
  }
}

// Query points under the two offset rules (the CPVS's, which the full map shares, and the
// equal-bytes map's own), their exact visibility and distance to a boundary.
void exactReference(const Inputs& in, const OrthoGrid& grid, const std::string& label, const Methods& m,
                    QueryPoints& atR, QueryPoints& atS) {
  const size_t n = in.count();
  for (QueryPoints* qp : {&atR, &atS}) {
    qp->points.resize(n);
    qp->inside.assign(n, 0);
    qp->lit.assign(n, 0);
    qp->distance.assign(n, 0);
  }
  forChunks(2 * n, label + " exact", in.report, [&](size_t k) {
    const size_t i = k % n;
    QueryPoints& qp = k < n ? atR : atS;
    const Vec3 q = k < n ? m.query.offsetPoint(in.points[i], in.normals[i], 1)
                         : m.equalBytes.offsetPoint(in.points[i], in.normals[i], 1);
    qp.points[i] = q;
    if (in.rays.closedNesting(q, -grid.frame.dir, in.shadowRay, in.options.bake.closed) > 0) {
      qp.inside[i] = 1;
      return;
    }
    const bool lit = exactlyLit(in.rays, grid, q);
    qp.lit[i] = lit;
    qp.distance[i] = boundaryDistance(in.rays, grid, q, in.normals[i], lit, in.firstRadius, in.maxRadius);
  });
}

// Binary lookups of every method against the exact answers.
void tallyBinary(const Inputs& in, const OrthoGrid& grid, Methods& m, const QueryPoints& atR, const QueryPoints& atS) {
  const size_t n = in.count();
  const double texel = grid.texelSize();
  std::vector<uint8_t> answer(n);
  tbb::parallel_for(size_t(0), n, [&](size_t i) { answer[i] = m.query.visibility(in.points[i], in.normals[i]) > 0.5f; });
  tally(m.cpvs, atR, answer, texel);
  tbb::parallel_for(size_t(0), n, [&](size_t i) { answer[i] = m.equalBytes.filteredAt(atS.points[i], 1) > 0.5f; });
  tally(m.eq, atS, answer, texel);
  tbb::parallel_for(size_t(0), n, [&](size_t i) { answer[i] = m.equalBytes.filteredAt(atR.points[i], 1) > 0.5f; });
  tally(m.eqOff, atR, answer, texel);
  if (m.full) {
    tbb::parallel_for(size_t(0), n, [&](size_t i) { answer[i] = m.fullMap.filteredAt(atR.points[i], 1) > 0.5f; });
    tally(m.fullRow, atR, answer, texel);
  }
  if (m.dagMh) {
    tbb::parallel_for(size_t(0), n, [&](size_t i) { answer[i] = m.dagMh->visibility(in.points[i], in.normals[i]) > 0.5f; });
    tally(m.dagMhRow, atR, answer, texel);
  }
  if (m.fullFloat) {
    tbb::parallel_for(size_t(0), n, [&](size_t i) { answer[i] = m.floatMap.filteredAt(atR.points[i], 1) > 0.5f; });
    tally(m.floatRow, atR, answer, texel);
  }
  if (m.everywhere) {
    tbb::parallel_for(size_t(0), n, [&](size_t i) { answer[i] = m.everywhere->visibility(in.points[i], in.normals[i]) > 0.5f; });
    tally(m.everywhereRow, atR, answer, texel);
  }
}

// PCF of every method against the exact fraction over each lookup's own footprint, at
// texel centres and averaged over each texel's area.
void measurePcf(const Inputs& in, const OrthoGrid& grid, const std::string& label, Methods& m, const QueryPoints& atR,
                const QueryPoints& atS) {
  const uint64_t R = grid.resolution();
  const size_t count = in.pcfSamples;
  for (size_t w = 0; w < kAccuracyPcfWidths.size(); ++w) {
    const int pcf = kAccuracyPcfWidths[w];
    constexpr double kNone = -1;  // not compared (inside closed geometry, or no full map)
    constexpr int kArea = kAreaRaysPerTexelSide;
    // Per method, the errors against texel-centre rays [0] and against the area average [1].
    std::array<std::vector<double>, 2> eCpvs, eEq, eEqOff, eFull, eDagMh, eFloat, eEverywhere;
    for (auto* e : {&eCpvs, &eEq, &eEqOff, &eFull, &eDagMh, &eFloat, &eEverywhere})
      for (auto& v : *e) v.assign(count, kNone);
    forChunks(count, label + " pcf " + std::to_string(pcf), in.report, [&](size_t i) {
      if (!atR.inside[i]) {
        const Vec3 q = m.query.offsetPoint(in.points[i], in.normals[i], pcf);
        const double cpvs = m.query.filtered(in.points[i], in.normals[i], pcf);
        const double fullLookup = m.full ? double(m.fullMap.filteredAt(q, pcf)) : 0.0;
        const double eqLookup = m.equalBytes.filteredAt(q, pcf);
        const double dagMh = m.dagMh ? double(m.dagMh->filtered(in.points[i], in.normals[i], pcf)) : 0.0;
        const double floatLookup = m.fullFloat ? double(m.floatMap.filteredAt(q, pcf)) : 0.0;
        const double everywhere = m.everywhere ? double(m.everywhere->filtered(in.points[i], in.normals[i], pcf)) : 0.0;
        for (int ref = 0; ref < 2; ++ref) {
          const int per = ref == 0 ? 1 : kArea;
          const double exactR = exactFootprintLit(in.rays, grid, uint32_t(R), q, pcf, per);
          eCpvs[ref][i] = pcfError(cpvs, exactR, pcf, per);
          if (m.dagMh) eDagMh[ref][i] = pcfError(dagMh, exactR, pcf, per);
          if (m.full) eFull[ref][i] = pcfError(fullLookup, exactR, pcf, per);
          if (m.fullFloat) eFloat[ref][i] = pcfError(floatLookup, exactR, pcf, per);
          if (m.everywhere) eEverywhere[ref][i] = pcfError(everywhere, exactR, pcf, per);
          eEqOff[ref][i] = pcfError(eqLookup, exactFootprintLit(in.rays, grid, m.equalSide, q, pcf, per), pcf, per);
        }
      }
      if (!atS.inside[i]) {
        const Vec3 q = m.equalBytes.offsetPoint(in.points[i], in.normals[i], pcf);
        const double eqLookup = m.equalBytes.filteredAt(q, pcf);
        for (int ref = 0; ref < 2; ++ref) {
          const int per = ref == 0 ? 1 : kArea;
          eEq[ref][i] = pcfError(eqLookup, exactFootprintLit(in.rays, grid, m.equalSide, q, pcf, per), pcf, per);
        }
      }
    });
    auto summarizeBoth = [&](AccuracyRow& row, std::array<std::vector<double>, 2>& errors) {
      for (int ref = 0; ref < 2; ++ref) {
        std::vector<double> kept;
        for (double e : errors[ref])
          if (e != kNone) kept.push_back(e);
        summarize((ref == 0 ? row.pcf : row.pcfArea)[w], pcf, kept);
      }
    };
    summarizeBoth(m.cpvs, eCpvs);
    summarizeBoth(m.eq, eEq);
    summarizeBoth(m.eqOff, eEqOff);
    summarizeBoth(m.fullRow, eFull);
    summarizeBoth(m.dagMhRow, eDagMh);
    summarizeBoth(m.floatRow, eFloat);
    summarizeBoth(m.everywhereRow, eEverywhere);
  }
}

// Lookup times: the whole batch of surface points, offsets included.
void timeLookups(const Inputs& in, const std::string& label, Methods& m) {
  in.report(label + " timing", 0, 1);
  std::vector<float> vis;
  const size_t n = in.count();
  const double minT = in.options.minTimingSeconds;
  const auto& p = in.points;
  const auto& nn = in.normals;
  m.cpvs.nsPerQuery = nsPerQuery(n, minT, [&] { m.query.batch(p, nn, 1, vis); });
  m.eq.nsPerQuery = nsPerQuery(n, minT, [&] { m.equalBytes.batch(p, nn, 1, vis); });
  if (m.full) m.fullRow.nsPerQuery = nsPerQuery(n, minT, [&] { m.fullMap.batch(p, nn, 1, vis); });
  if (m.dagMh) m.dagMhRow.nsPerQuery = nsPerQuery(n, minT, [&] { m.dagMh->batch(p, nn, 1, vis); });
  if (m.fullFloat) m.floatRow.nsPerQuery = nsPerQuery(n, minT, [&] { m.floatMap.batch(p, nn, 1, vis); });
  if (m.everywhere) m.everywhereRow.nsPerQuery = nsPerQuery(n, minT, [&] { m.everywhere->batch(p, nn, 1, vis); });
  for (size_t w = 0; w < kAccuracyPcfWidths.size(); ++w) {
    const int pcf = kAccuracyPcfWidths[w];
    m.cpvs.pcf[w].nsPerQuery = nsPerQuery(n, minT, [&] { m.query.batch(p, nn, pcf, vis); });
    m.eq.pcf[w].nsPerQuery = nsPerQuery(n, minT, [&] { m.equalBytes.batch(p, nn, pcf, vis); });
    if (m.full) m.fullRow.pcf[w].nsPerQuery = nsPerQuery(n, minT, [&] { m.fullMap.batch(p, nn, pcf, vis); });
    if (m.dagMh) m.dagMhRow.pcf[w].nsPerQuery = nsPerQuery(n, minT, [&] { m.dagMh->batch(p, nn, pcf, vis); });
    if (m.fullFloat) m.floatRow.pcf[w].nsPerQuery = nsPerQuery(n, minT, [&] { m.floatMap.batch(p, nn, pcf, vis); });
    if (m.everywhere)
      m.everywhereRow.pcf[w].nsPerQuery = nsPerQuery(n, minT, [&] { m.everywhere->batch(p, nn, pcf, vis); });
  }
  // The CPVS-offset row looks up the same map the same way, from another point.
  m.eqOff.nsPerQuery = m.eq.nsPerQuery;
  for (size_t w = 0; w < kAccuracyPcfWidths.size(); ++w) m.eqOff.pcf[w].nsPerQuery = m.eq.pcf[w].nsPerQuery;
  in.report(label + " timing", 1, 1);
}

}  // namespace

AccuracyReport measureAccuracy(const Scene& scene, const LightFrame& frame, const AccuracyOptions& options,
                               const ProgressFn& progress) {
  if (options.log2Resolutions.empty()) throw InputError("accuracy: no resolution to measure");
  if (options.samples < 1) throw InputError("accuracy: samples must be at least 1");
  // Translucent meshes cast no hard shadow (the sun bake leaves them out of the CPVS, a TOP
  // tree beside it darkens the light through them): every kind is measured on the hard
  // shadows of the opaque part.
  if (hasTranslucentMeshes(scene)) {
    AccuracyReport r = measureAccuracy(opaquePart(scene), frame, options, progress);
    r.scene = scene.name;
    return r;
  }
  const auto totalStart = std::chrono::steady_clock::now();
  const Reporter report(progress);
  std::vector<int> resolutions = options.log2Resolutions;
  std::sort(resolutions.begin(), resolutions.end());
  resolutions.erase(std::unique(resolutions.begin(), resolutions.end()), resolutions.end());

  // The grid's origin and extents depend only on the scene and the light, not on R: one
  // BVH and one set of samples serve every resolution.
  const OrthoGrid finest = makeGrid(scene, frame, resolutions.back());
  RayScene rays(scene, finest.origin);
  const std::vector<SurfaceSample> samples =
      options.cameras.empty()
          ? sampleReceivers(scene, rays, options.bake.closed, frame.dir, options.receivers, options.samples, options.seed)
          : sampleCameraViews(scene, rays, options.cameras, options.cameraAspect, options.samples, options.seed);
  if (samples.empty())
    throw InputError("accuracy: " + std::string(options.cameras.empty() ? "scene '" + scene.name + "' has no surface"
                                                                      : "the cameras see no surface of '" + scene.name + "'") +
                     " to sample");
  Inputs in{scene, frame, options, progress, report, rays, {}, {}, shadowRayLength(finest), sceneHash(scene), 0, 0, 0};
  for (const SurfaceSample& s : samples) {
    in.points.push_back(s.point);
    in.normals.push_back(s.normal);
  }

  AccuracyReport out;
  out.scene = scene.name;
  out.triangles = scene.triangleCount();
  out.lightDir = frame.dir;
  out.samples = in.count();
  out.pcfSamples = std::min<uint64_t>(options.pcfSamples, in.count());
  out.seed = options.seed;
  out.cameras = options.cameras;
  out.receivers = options.receivers.kind;
  out.receiverPcf = options.receivers.maxPcf;
  out.extent = finest.extent;
  out.depthExtent = finest.depthExtent;
  out.firstRadius = finest.extent / (16.0 * double(finest.resolution()));
  out.maxRadius = finest.extent / 16.0;
  out.threads = unsigned(tbb::this_task_arena::max_concurrency());
  out.timingSeconds = options.minTimingSeconds;
  in.firstRadius = out.firstRadius;
  in.maxRadius = out.maxRadius;
  in.pcfSamples = size_t(out.pcfSamples);

  for (int log2R : resolutions) {
    const OrthoGrid grid = makeGrid(scene, frame, log2R);
    const std::string label = resolutionLabel(grid.resolution());
    AccuracyRow cpvsRow;
    cpvsRow.method = AccuracyMethod::Cpvs;
    ShadowQuery query = bakeRow(in, grid, label, in.options.receivers, cpvsRow);
    Methods m{std::move(query), {}, {}, {}, false, false, 0, std::move(cpvsRow), {}, {}, {}, std::nullopt, {}, {}, std::nullopt, {}};
    baselineRows(in, grid, label, m);
    dagMhRow(in, grid, label, m);
    everywhereRow(in, grid, label, m);
    QueryPoints atR, atS;
    exactReference(in, grid, label, m, atR, atS);
    tallyBinary(in, grid, m, atR, atS);
    measurePcf(in, grid, label, m, atR, atS);
    timeLookups(in, label, m);
    for (AccuracyRow* r : {&m.cpvs, &m.eq, &m.eqOff, &m.fullRow, &m.dagMhRow, &m.floatRow, &m.everywhereRow})
      out.rows.push_back(std::move(*r));
  }
  out.seconds = secondsSince(totalStart);
  return out;
}

}  // namespace cpvs
