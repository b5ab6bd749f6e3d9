#include "cpvs/bake/receivers.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <numbers>
#include <numeric>
#include <type_traits>

#include "bake/receiver_reads.h"
#include "cpvs/bake/camera_views.h"
#include "cpvs/base/error.h"
#include "cpvs/light/lookup_mapping.h"
#include "cpvs/query/normal_offset.h"

namespace cpvs {

namespace {

// Slack, in voxels, on every bound: far above the rounding of any lookup's arithmetic
// (relative 1e-16 of coordinates below 2^18) and of a normal passed in float.
constexpr double kSlack = 0.01;
// The normal offset moves at most 1/256 more than asked (lookup_mapping.h); a little more.
constexpr double kOffsetExcess = 1.0 + 1.0 / 255.0;
constexpr int kLog2Cell = 8;
constexpr uint32_t kBandRows = 32;

static_assert(ReceiverSet::kMaxRings <= int(kMostRings), "ringRuns takes every ring of a row");

RingRows ringRows(const ReceiverSet::Span& s, const ReceiverSet::Ring& r) {
  return {r.support, s.dirX, s.invDirX, s.dirY, s.dirs, double(r.xMin), double(r.xMax)};
}

struct Point2 {
  double x, y;
};

// Fills a span's plane: false when the triangle's projection is too thin for its plane
// to bound depths (its depth range bounds them instead).
bool fitPlane(const Vec3 (&v)[3], ReceiverSet::Span& s) {
  const double ex1 = v[1].x - v[0].x, ey1 = v[1].y - v[0].y, ez1 = v[1].z - v[0].z;
  const double ex2 = v[2].x - v[0].x, ey2 = v[2].y - v[0].y, ez2 = v[2].z - v[0].z;
  const double det = ex1 * ey2 - ex2 * ey1;
  const double scale = std::max({std::fabs(ex1), std::fabs(ey1), std::fabs(ex2), std::fabs(ey2)});
  s.px = v[0].x;
  s.py = v[0].y;
  s.pz = v[0].z;
  s.gx = s.gy = 0;
  if (!(std::fabs(det) > 1e-9 * scale * scale)) return false;
  s.gx = (ez1 * ey2 - ez2 * ey1) / det;
  s.gy = (ex1 * ez2 - ex2 * ez1) / det;
  return std::isfinite(s.gx) && std::isfinite(s.gy) && std::fabs(s.gx) + std::fabs(s.gy) < 1e6;
}

// The directions of a span's supporting half-planes: normal to the triangle's edges
// and, when `sweep` has two points (a long sweep: a ground layer's seen from a low sun,
// which bounds alone would widen into a box), to the sweep; both senses of each.
void fitDirections(const Vec3 (&v)[3], const std::vector<Vec3>& sweep, ReceiverSet::Span& s) {
  s.dirs = 0;
  for (int e = 0; e < 4; ++e) {
    const Vec3 along = e < 3 ? v[(e + 1) % 3] - v[e] : sweep.size() == 2 ? sweep[1] - sweep[0] : Vec3{};
    if (along.x == 0 && along.y == 0) continue;  // bounds nothing
    for (int sign = 0; sign < 2; ++sign, ++s.dirs) {
      s.dirX[s.dirs] = sign ? along.y : -along.y;
      s.dirY[s.dirs] = sign ? -along.x : along.x;
      s.invDirX[s.dirs] = s.dirX[s.dirs] != 0 ? 1 / s.dirX[s.dirs] : 0;
    }
  }
}

// A ring's column bounds and supports: the triangle swept by `sweep` (its xy moved by
// each), dilated by the square of half-width h. False when it reaches no column.
bool fitRing(const Vec3 (&v)[3], const std::vector<Vec3>& sweep, double h, uint32_t R, const ReceiverSet::Span& s,
             ReceiverSet::Ring& ring) {
  std::vector<Point2> hull;
  for (const Vec3& o : sweep)
    for (const Vec3& p : v) hull.push_back({p.x + o.x, p.y + o.y});
  double minX = hull[0].x, maxX = minX, minY = hull[0].y, maxY = minY;
  for (const Point2& p : hull) {
    minX = std::min(minX, p.x), maxX = std::max(maxX, p.x);
    minY = std::min(minY, p.y), maxY = std::max(maxY, p.y);
  }
  // A column's centre is x + 0.5.
  const double last = double(R) - 1;
  const double x0 = std::ceil(minX - h - 0.5), x1 = std::floor(maxX + h - 0.5);
  const double y0 = std::ceil(minY - h - 0.5), y1 = std::floor(maxY + h - 0.5);
  if (!(x0 <= last && y0 <= last && x1 >= 0 && y1 >= 0 && x0 <= x1 && y0 <= y1)) return false;
  ring.xMin = int64_t(std::max(0.0, x0)), ring.xMax = int64_t(std::min(last, x1));
  ring.yMin = int64_t(std::max(0.0, y0)), ring.yMax = int64_t(std::min(last, y1));
  for (uint32_t k = 0; k < s.dirs; ++k) {
    const double ux = s.dirX[k], uy = s.dirY[k];
    double support = -std::numeric_limits<double>::infinity();
    for (const Point2& p : hull) support = std::max(support, ux * p.x + uy * p.y);
    // Rounding of the dot products (and of the reciprocal columnRange multiplies by) is
    // far below the slack carried by h.
    ring.support[k] = support + h * (std::fabs(ux) + std::fabs(uy));
  }
  return true;
}

// The world normal of a triangle (not normalized: lookups scale it away).
Vec3 triangleNormal(const Scene& scene, size_t t) {
  const Vec3 a = scene.vertex(t, 0), b = scene.vertex(t, 1), c = scene.vertex(t, 2);
  return cross(b - a, c - a);
}

// Labels of the volume's edge-connected parts, over vertices welded by exact position:
// each part's reads are hulled per column, which covers its interior.
std::vector<uint32_t> volumeParts(const Scene& volume) {
  std::map<std::array<double, 3>, uint32_t> welded;
  std::vector<uint32_t> vertexId(volume.positions.size());
  for (size_t i = 0; i < volume.positions.size(); ++i) {
    const Vec3& p = volume.positions[i];
    vertexId[i] = welded.emplace(std::array<double, 3>{p.x, p.y, p.z}, uint32_t(welded.size())).first->second;
  }
  std::vector<uint32_t> parent(welded.size());
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (size_t t = 0; t < volume.triangleCount(); ++t) {
    const uint32_t a = find(vertexId[volume.indices[3 * t]]);
    for (int c = 1; c < 3; ++c) parent[find(vertexId[volume.indices[3 * t + size_t(c)]])] = a;
  }
  std::vector<uint32_t> part(volume.triangleCount());
  std::map<uint32_t, uint32_t> number;
  for (size_t t = 0; t < part.size(); ++t)
    part[t] = number.emplace(find(vertexId[volume.indices[3 * t]]), uint32_t(number.size() + 1)).first->second;
  return part;
}


// A point in a spot light's frame: along u and v, and its view depth.
struct LightPoint {
  double a, b, zv;
};

// The polygon clipped to zLo <= zv (and zv <= zHi unless it is infinite); the points made
// on a clipping plane take its depth exactly.
std::vector<LightPoint> clipDepths(std::vector<LightPoint> poly, double zLo, double zHi) {
  for (int side = 0; side < 2 && !poly.empty(); ++side) {
    if (side == 1 && std::isinf(zHi)) break;
    const double plane = side ? zHi : zLo;
    std::vector<LightPoint> out;
    for (size_t i = 0; i < poly.size(); ++i) {
      const LightPoint& p = poly[i];
      const LightPoint& q = poly[(i + 1) % poly.size()];
      const double dp = side ? zHi - p.zv : p.zv - zLo, dq = side ? zHi - q.zv : q.zv - zLo;
      if (dp >= 0) out.push_back(p);
      if ((dp >= 0) != (dq >= 0)) {
        const double t = dp / (dp - dq);
        out.push_back({p.a + (q.a - p.a) * t, p.b + (q.b - p.b) * t, plane});
      }
    }
    poly = std::move(out);
  }
  return poly;
}

// Whether a span's column bounds meet the columns [x0, x1] x [y0, y1].
template <class S>
bool reachesRectangle(const S& s, uint64_t x0, uint64_t y0, uint64_t x1, uint64_t y1) {
  return s.xMax >= int64_t(x0) && s.xMin <= int64_t(x1) && s.yMax >= int64_t(y0) && s.yMin <= int64_t(y1);
}

}  // namespace

std::vector<uint8_t> receivingSides(const Scene& scene, const ReceiverDeclaration& d) {
  const size_t n = scene.triangleCount();
  std::vector<uint8_t> sides(n);
  switch (d.kind) {
    case ReceiverKind::Everywhere:
    case ReceiverKind::SurfacesTwoSided:
      for (size_t t = 0; t < n; ++t) sides[t] = scene.closed[t] ? 1 : 3;
      return sides;
    case ReceiverKind::Surfaces:
    case ReceiverKind::Volume:
      std::fill(sides.begin(), sides.end(), uint8_t(1));
      return sides;
    case ReceiverKind::Cameras:
      break;
  }
  if (d.cameraVisibility == CameraVisibility::Sampled) {
    const Hash128 sceneKey = sceneHash(scene), declarationKey = receiverHash(d);
    std::lock_guard lock(d.seen->mutex);
    if (d.seen->sides.size() != n || d.seen->scene != sceneKey || d.seen->declaration != declarationKey) {
      // Isolated: a thread waiting here must not take up another task that needs the lock.
      tbb::this_task_arena::isolate([&] { d.seen->sides = sampleCameraViews(scene, d).sides; });
      d.seen->scene = sceneKey, d.seen->declaration = declarationKey;
    }
    return d.seen->sides;
  }
  // Faced: every place a camera can be, as a box (a point's is the point, a path segment's
  // its bounds).
  std::vector<std::pair<Vec3, Vec3>> places = d.cameraRegions;
  for (const Vec3& p : d.cameraPoints) places.push_back({p, p});
  for (const auto& path : d.cameraPaths) {
    places.push_back({path[0], path[0]});
    for (size_t i = 1; i < path.size(); ++i)
      places.push_back({min(path[i - 1], path[i]), max(path[i - 1], path[i])});
  }
  const double reach = d.viewDistance;
  for (size_t t = 0; t < n; ++t) {
    const bool open = !scene.closed[t];
    const Vec3 a = scene.vertex(t, 0), b = scene.vertex(t, 1), c = scene.vertex(t, 2);
    const Vec3 nt = cross(b - a, c - a);
    const Vec3 lo{std::min({a.x, b.x, c.x}), std::min({a.y, b.y, c.y}), std::min({a.z, b.z, c.z})};
    const Vec3 hi{std::max({a.x, b.x, c.x}), std::max({a.y, b.y, c.y}), std::max({a.z, b.z, c.z})};
    for (const auto& [rlo, rhi] : places) {
      if (lo.x > rhi.x + reach || hi.x < rlo.x - reach || lo.y > rhi.y + reach || hi.y < rlo.y - reach ||
          lo.z > rhi.z + reach || hi.z < rlo.z - reach)
        continue;
      // The place's points on each side of the triangle's plane: its extreme corners along n.
      const Vec3 far{nt.x > 0 ? rhi.x : rlo.x, nt.y > 0 ? rhi.y : rlo.y, nt.z > 0 ? rhi.z : rlo.z};
      const Vec3 near{nt.x > 0 ? rlo.x : rhi.x, nt.y > 0 ? rlo.y : rhi.y, nt.z > 0 ? rlo.z : rhi.z};
      if (dot(nt, far - a) > 0) sides[t] |= 1;
      if (open && dot(nt, near - a) < 0) sides[t] |= 2;
    }
  }
  return sides;
}

bool walkable(const Scene& scene, const ReceiverDeclaration& d, size_t t) {
  if (!(d.groundLayer > 0)) return false;
  const Vec3 n = triangleNormal(scene, t);
  const double len = length(n);
  // A part in 10^9 of slack: a ramp of exactly the limit counts, whatever the last bit of
  // the cosine (the C library's, which may differ between a client and a worker).
  return len > 0 && n.y >= std::cos(d.groundSlopeDeg * std::numbers::pi / 180.0) * len * (1 - 1e-9);
}

void checkReceiverDeclaration(const ReceiverDeclaration& d) {
  if (!isOptionValue<ReceiverKind>(int64_t(d.kind))) throw InputError("receivers: unknown kind " + std::to_string(int(d.kind)));
  checkPcfWidth(d.maxPcf);
  const bool wantsVolume = d.kind == ReceiverKind::Volume, cameras = d.kind == ReceiverKind::Cameras;
  if (!wantsVolume && !cameras && d.volume.triangleCount() != 0)
    throw InputError(std::string("receivers: a volume is declared for '") + optionName(d.kind) +
                     "' receivers; only 'volume' and 'cameras' take one");
  if (!isOptionValue<CameraVisibility>(int64_t(d.cameraVisibility)))
    throw InputError("receivers: unknown camera visibility " + std::to_string(int(d.cameraVisibility)));
  const bool anyCamera = !d.cameraRegions.empty() || !d.cameraPoints.empty() || !d.cameraPaths.empty() ||
                         d.viewDistance != 0 || d.cameraVisibility != CameraVisibility::Faced ||
                         d.cameraSpacing != 0 || d.cameraRays != 0;
  if (!cameras && anyCamera)
    throw InputError("receivers: camera places, a view distance and a camera visibility are for 'cameras' receivers only");
  if (cameras) {
    if (d.cameraRegions.empty() && d.cameraPoints.empty() && d.cameraPaths.empty())
      throw InputError("receivers: 'cameras' needs at least one camera region, point or path");
    for (const auto& [lo, hi] : d.cameraRegions)
      if (!(isFinite(lo) && isFinite(hi) && lo.x < hi.x && lo.y < hi.y && lo.z < hi.z))
        throw InputError("receivers: a camera region is not finite with min < max");
    for (const Vec3& p : d.cameraPoints)
      if (!isFinite(p)) throw InputError("receivers: a camera point is not finite");
    for (const auto& path : d.cameraPaths) {
      if (path.empty()) throw InputError("receivers: a camera path has no points");
      for (const Vec3& p : path)
        if (!isFinite(p)) throw InputError("receivers: a camera path's point is not finite");
    }
    if (!(d.viewDistance > 0) || !std::isfinite(d.viewDistance))
      throw InputError("receivers: 'cameras' needs a positive, finite view distance");
    const bool sampled = d.cameraVisibility == CameraVisibility::Sampled;
    if (!sampled && (d.cameraSpacing != 0 || d.cameraRays != 0))
      throw InputError("receivers: a camera spacing and rays per face are for sampled camera visibility only");
    if (!(d.cameraSpacing >= 0 && std::isfinite(d.cameraSpacing)))
      throw InputError("receivers: the camera spacing must be a finite number >= 0 (0: a sixteenth of the view distance)");
    if (d.cameraRays > kMaxCameraRays)
      throw InputError("receivers: at most " + std::to_string(kMaxCameraRays) + " rays per side of a cube face, not " +
                       std::to_string(d.cameraRays));
    checkCameraBudget(d);
  }
  if (!(d.groundLayer >= 0 && std::isfinite(d.groundLayer)))
    throw InputError("receivers: the ground layer's height must be a finite number >= 0");
  if (!(d.groundLayerFrom >= 0 && (d.groundLayerFrom < d.groundLayer || d.groundLayerFrom == 0)))
    throw InputError("receivers: the ground layer must start at 0 or above and below its top");
  if (!(d.groundSlopeDeg >= 0 && d.groundSlopeDeg < 90))
    throw InputError("receivers: the ground layer's slope must be at least 0 and below 90 degrees");
  if (!wantsVolume && !cameras && d.groundLayer > 0)
    throw InputError(std::string("receivers: a ground layer is declared for '") + optionName(d.kind) +
                     "' receivers; only 'volume' and 'cameras' take one");
  if (wantsVolume && d.volume.triangleCount() == 0 && d.groundLayer == 0)
    throw InputError("receivers: 'volume' needs a volume (a closed mesh file, boxes or a ground layer)");
  if (d.volume.triangleCount() != 0 && std::find(d.volume.closed.begin(), d.volume.closed.end(), 0) != d.volume.closed.end()) {
    const size_t open = size_t(std::count(d.volume.closed.begin(), d.volume.closed.end(), 0));
    throw InputError("receivers: the volume must be closed (watertight and consistently oriented); " +
                     std::to_string(open) + " of its " + std::to_string(d.volume.triangleCount()) +
                     " triangles belong to open parts");
  }
}

Hash128 receiverHash(const ReceiverDeclaration& d) {
  if (d.kind == ReceiverKind::Everywhere) return {};
  const Hash128 volume = d.volume.triangleCount() ? sceneHash(d.volume) : Hash128{};
  std::vector<double> words{double(d.kind), double(d.maxPcf), double(volume.lo >> 32), double(volume.lo & 0xFFFFFFFF),
                            double(volume.hi >> 32), double(volume.hi & 0xFFFFFFFF), d.viewDistance};
  // Camera regions alone (faced) keep the words they always had. Any other camera place,
  // or sampled visibility, tags the first word and counts every list first, so that no
  // two declarations share their words.
  const bool tagged =
      !d.cameraPoints.empty() || !d.cameraPaths.empty() || d.cameraVisibility == CameraVisibility::Sampled;
  if (tagged) {
    words[0] += 1000;
    words.insert(words.end(), {double(d.cameraRegions.size()), double(d.cameraPoints.size()),
                               double(d.cameraPaths.size()), double(d.cameraVisibility), cameraSpacing(d),
                               double(cameraRaysPerSide(d))});
  }
  for (const auto& [lo, hi] : d.cameraRegions)
    for (double v : {lo.x, lo.y, lo.z, hi.x, hi.y, hi.z}) words.push_back(v);
  for (const Vec3& p : d.cameraPoints) words.insert(words.end(), {p.x, p.y, p.z});
  for (const auto& path : d.cameraPaths) {
    words.push_back(double(path.size()));
    for (const Vec3& p : path) words.insert(words.end(), {p.x, p.y, p.z});
  }
  // Only a declared layer adds words: declarations without one keep their hashes.
  if (d.groundLayer > 0) words.insert(words.end(), {-1.0, d.groundLayer, d.groundSlopeDeg});
  if (d.groundLayerFrom > 0) words.insert(words.end(), {-2.0, d.groundLayerFrom});
  return contentHash(words.data(), words.size() * sizeof(double));
}

ReceiverSet::ReceiverSet(const Scene& scene, const OrthoGrid& grid, const ReceiverDeclaration& d)
    : kind_(d.kind), maxPcf_(d.maxPcf), R_(uint32_t(grid.resolution())) {
  checkReceiverDeclaration(d);
  if (kind_ == ReceiverKind::Everywhere) return;
  const LookupMapping m = grid.lookupMapping();
  // Offsets reach 2^shift times further across than deep (lookup_mapping.h, offsetExtent).
  const int shift = grid.depthShift();
  const double rho = 0.5 * (maxPcf_ - 1);  // footprint radius, texels
  const double half = rho + 0.5;           // a column's window: the footprint around a texel
  // A group of lookups: the sweep of their points' offsets, the half-width of their
  // footprint's window and their read depths relative to the plane.
  struct RingSpec {
    std::vector<Vec3> sweep;
    double coverHalf, loOff, hiOff;
  };
  // `s` holds the triangle's plane (fitPlane); the rest is filled here. `alongSweep`: also
  // bound the coverage along the (one) ring's sweep.
  auto add = [&](Span s, const Vec3 (&v)[3], const std::vector<RingSpec>& specs, bool alongSweep, double depthPad,
                 double sweepLo, double sweepHi, uint32_t part) {
    s.part = part;
    fitDirections(v, alongSweep ? specs[0].sweep : std::vector<Vec3>{}, s);
    s.rings = 0;
    for (const RingSpec& spec : specs) {
      Ring& ring = s.ring[s.rings];
      if (!fitRing(v, spec.sweep, spec.coverHalf + kSlack, R_, s, ring)) continue;
      ring.loOff = spec.loOff - kSlack;
      ring.hiOff = spec.hiOff + kSlack;
      if (s.rings == 0) {
        s.xMin = ring.xMin, s.xMax = ring.xMax, s.yMin = ring.yMin, s.yMax = ring.yMax;
      } else {
        s.xMin = std::min(s.xMin, ring.xMin), s.xMax = std::max(s.xMax, ring.xMax);
        s.yMin = std::min(s.yMin, ring.yMin), s.yMax = std::max(s.yMax, ring.yMax);
      }
      ++s.rings;
    }
    if (s.rings == 0) return;
    const double zMin = std::min({v[0].z, v[1].z, v[2].z}), zMax = std::max({v[0].z, v[1].z, v[2].z});
    s.zLo = zMin + sweepLo - depthPad - kSlack;
    s.zHi = zMax + sweepHi + depthPad + kSlack;
    if (s.zHi < 0) return;  // in front of the grid: lit without reading the DAG
    spans_.push_back(s);
  };

  // Surfaces: each side a receiver may be on, moved along its normal in voxels.
  const std::vector<uint8_t> receiving = receivingSides(scene, d);
  // At most one span per side, volume triangle and walkable triangle: reserved at once, so
  // that the spans (hundreds of bytes each) are written once, not copied as they grow.
  size_t most = d.volume.triangleCount() + (d.groundLayer > 0 ? scene.triangleCount() : 0);
  for (const uint8_t sides : receiving) most += size_t(std::popcount(unsigned(sides)));
  spans_.reserve(most);
  for (size_t t = 0; t < scene.triangleCount(); ++t) {
    const uint8_t sides = receiving[t];
    if (sides == 0) continue;
    Vec3 v[3];
    for (int c = 0; c < 3; ++c) v[c] = mappedVoxel(m, scene.vertex(t, c));
    const Vec3 nWorld = triangleNormal(scene, t);
    Span plane{};
    plane.planar = fitPlane(v, plane);
    const double g = std::fabs(plane.gx) + std::fabs(plane.gy);
    for (int side = 0; side < 2; ++side) {
      if (!(sides & (1 << side))) continue;
      Vec3 nv = mappedDirection(m, side ? -nWorld : nWorld);
      const double big = offsetExtent(nv, shift);  // the component the lookup's offset measures
      if (!(big > 0) || !std::isfinite(big)) continue;
      // A ring per pair of filter widths (1-3, 5-7, 9): a wide filter's offset and window
      // are not a narrow one's, and bounding all together pins texels that none reads
      // (the peer's city at 16K: 11.8 MB with one ring, 9.2 MB with these three, 9.0 MB
      // with one per width, which costs more time per row than it saves bytes).
      double sweepLo = std::numeric_limits<double>::infinity(), sweepHi = -sweepLo;
      std::vector<RingSpec> specs;
      for (int narrow = 1; narrow <= maxPcf_; narrow += 4) {
        const int wide = std::min(narrow + 2, maxPcf_);
        RingSpec spec{{}, 0.5 * (wide - 1) + 0.5, std::numeric_limits<double>::infinity(),
                      -std::numeric_limits<double>::infinity()};
        for (int width : {narrow, wide})
          for (double f : {1.0, kOffsetExcess}) {
            const Vec3 o = nv * (normalOffsetVoxels(width) * f / big);
            const double r = 0.5 * (width - 1) + 0.5;
            const double shift = o.z - plane.gx * o.x - plane.gy * o.y;
            if (plane.planar) {
              spec.loOff = std::min(spec.loOff, shift - g * r);
              spec.hiOff = std::max(spec.hiOff, shift + g * r);
            }
            sweepLo = std::min(sweepLo, o.z);
            sweepHi = std::max(sweepHi, o.z);
            // Offsets and windows grow with the width: the two ends bound the pair.
            if ((width == narrow && f == 1.0) || (width == wide && f != 1.0)) spec.sweep.push_back(o);
          }
        specs.push_back(std::move(spec));
      }
      add(plane, v, specs, false, 0, sweepLo, sweepHi, 0);
    }
  }

  // Volumes: any point inside, any normal: reads within the offset's box (2^shift times
  // wider than deep), over the
  // footprint, hulled per part.
  if (d.volume.triangleCount() != 0) {
    const std::vector<uint32_t> parts = volumeParts(d.volume);
    const double cube = normalOffsetVoxels(maxPcf_) * kOffsetExcess;
    for (size_t t = 0; t < d.volume.triangleCount(); ++t) {
      Vec3 v[3];
      for (int c = 0; c < 3; ++c) v[c] = mappedVoxel(m, d.volume.vertex(t, c));
      Span plane{};
      plane.planar = fitPlane(v, plane);
      const double g = std::fabs(plane.gx) + std::fabs(plane.gy);
      const double window = half + std::ldexp(cube, shift);
      add(plane, v, {{{Vec3{}}, window, -g * window - cube, g * window + cube}}, false, cube, 0, 0, parts[t]);
    }
  }

  // The ground layer: per walkable triangle the prism between its copies raised by the
  // layer's bottom and top, any point in it with any normal (the volume's cube): the reads
  // at a column lie between the two copies' planes, widened as a volume's.
  if (d.groundLayer > 0) {
    // Taller than the grid it would sweep across all of it: no level has such a layer.
    const double tallest = 2 * std::max(grid.extent, grid.sceneDepthExtent());
    if (d.groundLayer > tallest)
      throw InputError("receivers: a ground layer " + std::to_string(d.groundLayer) +
                       " scene units tall is taller than twice the scene's grid (" + std::to_string(tallest) + ")");
    const double cube = normalOffsetVoxels(maxPcf_) * kOffsetExcess;
    const double window = half + std::ldexp(cube, shift);
    const Vec3 bottom{0, d.groundLayerFrom, 0};
    const Vec3 up = mappedDirection(m, Vec3{0, d.groundLayer - d.groundLayerFrom, 0});
    for (size_t t = 0; t < scene.triangleCount(); ++t) {
      if (!walkable(scene, d, t)) continue;
      Vec3 v[3];
      for (int c = 0; c < 3; ++c) v[c] = mappedVoxel(m, scene.vertex(t, c) + bottom);
      Span plane{};
      plane.planar = fitPlane(v, plane);
      const double g = std::fabs(plane.gx) + std::fabs(plane.gy);
      const double rise = plane.planar ? up.z - plane.gx * up.x - plane.gy * up.y : 0;
      add(plane, v, {{{Vec3{}, up}, window, std::min(0.0, rise) - g * window - cube, std::max(0.0, rise) + g * window + cube}},
          true, cube, std::min(0.0, up.z), std::max(0.0, up.z), 0);
    }
  }

  indexCells(spans_, grid.log2Resolution);
}

template <class S>
void ReceiverSet::indexCells(const std::vector<S>& spans, int log2Resolution) {
  log2Cell_ = std::min(log2Resolution, kLog2Cell);
  cellsPerSide_ = uint64_t(R_) >> log2Cell_;
  const size_t cells = size_t(cellsPerSide_ * cellsPerSide_);
  cellBegin_.assign(cells + 1, 0);
  auto forCells = [&](const S& s, auto&& fn) {
    for (int64_t cy = s.yMin >> log2Cell_; cy <= s.yMax >> log2Cell_; ++cy)
      for (int64_t cx = s.xMin >> log2Cell_; cx <= s.xMax >> log2Cell_; ++cx) fn(size_t(cy) * cellsPerSide_ + size_t(cx));
  };
  uint64_t entries = 0;
  for (const S& s : spans) forCells(s, [&](size_t c) { ++cellBegin_[c + 1], ++entries; });
  if (entries > std::numeric_limits<uint32_t>::max())
    throw InputError("receivers: the declared receivers reach too much of the grid to be listed (" +
                     std::to_string(entries) + " cell entries)");
  for (size_t c = 0; c < cells; ++c) cellBegin_[c + 1] += cellBegin_[c];
  cellItems_.resize(cellBegin_[cells]);
  std::vector<uint32_t> fill(cellBegin_.begin(), cellBegin_.end() - 1);
  for (uint32_t i = 0; i < spans.size(); ++i) forCells(spans[i], [&](size_t c) { cellItems_[fill[c]++] = i; });
}

ReceiverSet::ReceiverSet(const Scene& scene, const PerspectiveGrid& grid, const ReceiverDeclaration& d)
    : kind_(d.kind), maxPcf_(d.maxPcf), R_(uint32_t(grid.resolution())) {
  checkReceiverDeclaration(d);
  if (kind_ == ReceiverKind::Everywhere) return;
  spot_.emplace(grid);
  const LightFrame& f = grid.frame();
  const double R = double(R_), t = grid.tanHalfFov(), centre = 0.5 * R, scale = centre / t;
  // Any normal offset moves a lookup at most `cube` voxels along each axis; its footprint
  // reaches `window` texels beyond the texel it lands in.
  const double cube = normalOffsetVoxels(maxPcf_) * kOffsetExcess + kSlack;
  const double window = 0.5 * (maxPcf_ - 1) + cube + kSlack;
  // Depths whose voxel z is more than an offset before slice 0 or beyond slice R - 1 read
  // nothing (a lookup there is lit before near, dark beyond far, without a read).
  const double b0 = grid.sliceBoundary(0), b1 = grid.sliceBoundary(1);
  const double bR = grid.sliceBoundary(R_), bLast = grid.sliceBoundary(R_ - 1);
  double zNear = b0 - (cube + 1) * (b1 - b0);
  const double zFar = bR + (cube + 1) * (bR - bLast);
  // When every depth in front of the light may reach slice 0 (a coarse grid over a deep
  // range), triangles are clipped a thousandth of near from the light instead: what lies
  // closer projects outside the grid unless it is within `apexReach` of the light's axis,
  // and a triangle that comes that close reads from slice 0 wherever it projects.
  const bool clipsAtApex = !(zNear > 0);
  if (clipsAtApex) zNear = b0 * 1e-3;
  const double apexReach = t * (1 + 2 * (window + 1) / R) * zNear;

  auto toLight = [&](const Vec3& p) {
    const Vec3 q = p - grid.position();
    return LightPoint{dot(q, f.u), dot(q, f.v), dot(q, f.dir)};
  };
  // Adds a triangle's span, unless it reads nothing. `zLoOff`, `zHiOff`: its reads' voxel
  // z relative to its points'; `part` > 0: a closed part's boundary, not clipped beyond
  // far (its interior there may still read slices, and only a hull of its whole boundary
  // bounds them). `nearClipped` says whether some of it was clipped before near.
  auto add = [&](const Vec3 (&v)[3], double zLoOff, double zHiOff, uint32_t part, bool& nearClipped) {
    nearClipped = false;
    std::vector<LightPoint> poly;
    for (const Vec3& p : v) poly.push_back(toLight(p));
    double zMin = poly[0].zv, zMax = zMin;
    double aMin = poly[0].a, aMax = aMin, bMin = poly[0].b, bMax = bMin;
    for (const LightPoint& p : poly) {
      zMin = std::min(zMin, p.zv), zMax = std::max(zMax, p.zv);
      aMin = std::min(aMin, p.a), aMax = std::max(aMax, p.a), bMin = std::min(bMin, p.b), bMax = std::max(bMax, p.b);
    }
    if (!(zMax > zNear) || (part == 0 && !(zMin < zFar))) return;
    nearClipped = zMin < zNear;
    const bool atApex = clipsAtApex && zMin < zNear && aMin <= apexReach && aMax >= -apexReach &&
                        bMin <= apexReach && bMax >= -apexReach;
    FrustumSpan s{};
    s.part = part;
    s.window = window;
    s.zLoOff = atApex ? -std::numeric_limits<double>::infinity() : zLoOff - kSlack;
    s.zHiOff = zHiOff + kSlack;
    // 1 / zv across the plane: n . q = n . q0 along the ray q = zv (xi, eta, 1).
    const Vec3 q0{poly[0].a, poly[0].b, poly[0].zv}, q1{poly[1].a, poly[1].b, poly[1].zv}, q2{poly[2].a, poly[2].b, poly[2].zv};
    const Vec3 n = cross(q1 - q0, q2 - q0);
    const double dPlane = dot(n, q0);
    const double size = std::max({length(q0), length(q1), length(q2)});
    s.planar = std::fabs(dPlane) > 1e-7 * length(n) * size && std::isfinite(dPlane);
    if (s.planar) {
      // xi = (x - centre) / scale.
      s.wx = n.x / (dPlane * scale);
      s.wy = n.y / (dPlane * scale);
      s.w0 = (n.z - (n.x + n.y) * centre / scale) / dPlane;
      s.planar = std::isfinite(s.wx) && std::isfinite(s.wy) && std::isfinite(s.w0);
      // Rounding of the fit and of the window's sums: far below relative 1e-6 of the
      // terms at any column of the grid and its window.
      const double reach = R + 2 * window + 2;
      s.slack = 1e-6 * (std::fabs(s.w0) + (std::fabs(s.wx) + std::fabs(s.wy)) * reach);
    }
    poly = clipDepths(std::move(poly), zNear, part == 0 ? zFar : std::numeric_limits<double>::infinity());
    if (poly.empty()) return;
    double xLo = std::numeric_limits<double>::infinity(), xHi = -xLo, yLo = xLo, yHi = -xLo;
    double wLo = xLo, wHi = -xLo;
    for (const LightPoint& p : poly) {
      const double x = p.a / p.zv * scale + centre, y = p.b / p.zv * scale + centre;
      xLo = std::min(xLo, x), xHi = std::max(xHi, x), yLo = std::min(yLo, y), yHi = std::max(yHi, y);
      wLo = std::min(wLo, 1 / p.zv), wHi = std::max(wHi, 1 / p.zv);
    }
    if (atApex) {
      // Its points nearest the light are clipped away: they may land on any column.
      xLo = yLo = -std::numeric_limits<double>::infinity(), xHi = yHi = -xLo;
      s.planar = false;
    }
    s.wLo = wLo * (1 - 1e-12);
    s.wHi = wHi * (1 + 1e-12);
    const double last = R - 1;
    const double x0 = std::floor(xLo - window), x1 = std::floor(xHi + window);
    const double y0 = std::floor(yLo - window), y1 = std::floor(yHi + window);
    if (!(x0 <= last && y0 <= last && x1 >= 0 && y1 >= 0)) return;
    s.xMin = int64_t(std::max(0.0, x0)), s.xMax = int64_t(std::min(last, x1));
    s.yMin = int64_t(std::max(0.0, y0)), s.yMax = int64_t(std::min(last, y1));
    frustumSpans_.push_back(s);
  };

  // Surfaces: a side facing the light reads towards it (its offset's voxel z is <= 0, as
  // the sign of n . (p - light) is the same everywhere on the plane), one facing away
  // behind it; a plane through the light, either way.
  const std::vector<uint8_t> receiving = receivingSides(scene, d);
  for (size_t i = 0; i < scene.triangleCount(); ++i) {
    if (receiving[i] == 0) continue;
    const Vec3 v[3] = {scene.vertex(i, 0), scene.vertex(i, 1), scene.vertex(i, 2)};
    const Vec3 n = triangleNormal(scene, i), q = v[0] - grid.position();
    const double facing = dot(n, q);
    if (!std::isfinite(facing)) continue;
    const bool grazing = std::fabs(facing) <= 1e-4 * length(n) * length(q);
    double lo = 0, hi = 0;
    for (int side = 0; side < 2; ++side) {
      if (!(receiving[i] & (1 << side))) continue;
      const double towards = side ? -facing : facing;  // < 0: this side faces the light
      if (grazing || towards < 0) lo = -cube;
      if (grazing || towards > 0) hi = cube;
    }
    bool clipped = false;
    add(v, lo, hi, 0, clipped);
  }

  // Closed parts (the volume's, and a ground layer's prisms): any point inside, any
  // normal; hulled per column. A part clipped before near reads from slice 0 on.
  uint32_t parts = 0;
  auto addPart = [&](const std::vector<std::array<Vec3, 3>>& triangles, uint32_t part) {
    const size_t first = frustumSpans_.size();
    bool fromFront = false;
    for (const auto& tri : triangles) {
      const Vec3 v[3] = {tri[0], tri[1], tri[2]};
      bool clipped = false;
      add(v, -cube, cube, part, clipped);
      fromFront |= clipped;
    }
    if (fromFront)
      for (size_t k = first; k < frustumSpans_.size(); ++k) frustumSpans_[k].zLoOff = -std::numeric_limits<double>::infinity();
  };
  if (d.volume.triangleCount() != 0) {
    const std::vector<uint32_t> partOf = volumeParts(d.volume);
    std::map<uint32_t, std::vector<std::array<Vec3, 3>>> byPart;
    for (size_t i = 0; i < d.volume.triangleCount(); ++i)
      byPart[partOf[i]].push_back({d.volume.vertex(i, 0), d.volume.vertex(i, 1), d.volume.vertex(i, 2)});
    for (const auto& [k, triangles] : byPart) addPart(triangles, ++parts);
  }
  if (d.groundLayer > 0) {
    const Vec3 bottom{0, d.groundLayerFrom, 0}, top{0, d.groundLayer, 0};
    for (size_t i = 0; i < scene.triangleCount(); ++i) {
      if (!walkable(scene, d, i)) continue;
      Vec3 lo[3], hi[3];
      for (int c = 0; c < 3; ++c) lo[c] = scene.vertex(i, c) + bottom, hi[c] = scene.vertex(i, c) + top;
      std::vector<std::array<Vec3, 3>> prism{{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}};
      for (int e = 0; e < 3; ++e) {
        const int f = (e + 1) % 3;
        prism.push_back({lo[e], lo[f], hi[f]});
        prism.push_back({lo[e], hi[f], hi[e]});
      }
      addPart(prism, ++parts);
    }
  }
  indexCells(frustumSpans_, grid.log2Resolution());
}

ReceiverSet::FrustumRead ReceiverSet::frustumReads(const FrustumSpan& s, int64_t x, int64_t y, uint32_t& a,
                                                   uint32_t& b, uint32_t* hints) const {
  double lo = s.wLo, hi = s.wHi;
  if (s.planar) {
    // The window's extremes of w0 + wx x + wy y: the row's part first, then the column's,
    // with one slack for the whole grid, so each is monotone in x.
    const double ya = double(y) - s.window, yb = double(y) + 1 + s.window;
    const double xa = double(x) - s.window, xb = double(x) + 1 + s.window;
    const double low = (s.w0 + std::min(s.wy * ya, s.wy * yb) - s.slack) + std::min(s.wx * xa, s.wx * xb);
    const double high = (s.w0 + std::max(s.wy * ya, s.wy * yb) + s.slack) + std::max(s.wx * xa, s.wx * xb);
    if (!(high >= s.wLo)) return kNoneBefore;  // every point in the window is farther than the triangle
    if (!(low <= s.wHi)) return kNoneAfter;    // nearer
    lo = std::max(lo, low);
    hi = std::min(hi, high);
  }
  const PerspectiveGrid& g = *spot_;
  const double top = double(R_) - 1;
  const double zLo = g.voxelZ(1 / hi, hints[0]) + s.zLoOff, zHi = g.voxelZ(1 / lo, hints[1]) + s.zHiOff;
  if (!(zLo <= top)) return kNoneBefore;  // behind the grid
  if (!(zHi >= 0)) return kNoneAfter;     // in front of it
  a = uint32_t(std::max(0.0, zLo));
  b = uint32_t(std::min(top, zHi));
  return kReads;
}

template <class Fn>
void ReceiverSet::forFrustumRow(const FrustumSpan& s, int64_t y, int64_t xa, int64_t xb, Fn&& fn) const {
  struct End {
    FrustumRead read;
    uint32_t a, b;
  };
  uint32_t hints[2] = {0, 0};
  auto at = [&](int64_t x) {
    End e{kNoneBefore, 0, 0};
    e.read = frustumReads(s, x, y, e.a, e.b, hints);
    return e;
  };
  auto same = [](const End& p, const End& q) { return p.read == q.read && (p.read != kReads || (p.a == q.a && p.b == q.b)); };
  auto emit = [&](int64_t l, int64_t r, const End& e) {
    if (e.read == kReads)
      for (int64_t x = l; x <= r; ++x) fn(x, e.a, e.b);
  };
  if (xa > xb) return;
  if (!s.planar) {  // the same everywhere
    emit(xa, xb, at(xa));
    return;
  }
  struct Run {
    int64_t l, r;
    End el, er;
  };
  std::vector<Run> stack;
  for (int64_t block = xa & ~int64_t(63); block <= xb; block += 64) {
    const int64_t l = std::max(block, xa), r = std::min(block + 63, xb);
    stack.push_back({l, r, at(l), at(r)});
    while (!stack.empty()) {
      const Run run = stack.back();
      stack.pop_back();
      if (same(run.el, run.er)) {
        emit(run.l, run.r, run.el);
      } else if (run.r - run.l < 8) {  // short: each column (its ends known)
        emit(run.l, run.l, run.el);
        for (int64_t x = run.l + 1; x < run.r; ++x) emit(x, x, at(x));
        emit(run.r, run.r, run.er);
      } else {
        const int64_t m = run.l + (run.r - run.l) / 2;
        stack.push_back({m + 1, run.r, at(m + 1), run.er});
        stack.push_back({run.l, m, run.el, at(m)});
      }
    }
  }
}

ReceiverSet ReceiverSet::everywhere(uint64_t resolution) {
  ReceiverSet set;
  set.R_ = uint32_t(resolution);
  return set;
}

bool ReceiverSet::touchesRectangle(uint64_t x0, uint64_t y0, uint64_t width, uint64_t height) const {
  if (kind_ == ReceiverKind::Everywhere) return true;
  if (width == 0 || height == 0 || x0 >= R_ || y0 >= R_) return false;
  const uint64_t x1 = std::min<uint64_t>(x0 + width, R_) - 1, y1 = std::min<uint64_t>(y0 + height, R_) - 1;
  for (uint64_t cy = y0 >> log2Cell_; cy <= y1 >> log2Cell_; ++cy)
    for (uint64_t cx = x0 >> log2Cell_; cx <= x1 >> log2Cell_; ++cx) {
      const size_t c = size_t(cy * cellsPerSide_ + cx);
      for (uint32_t k = cellBegin_[c]; k < cellBegin_[c + 1]; ++k) {
        const uint32_t i = cellItems_[k];
        const bool hit = spot_ ? reachesRectangle(frustumSpans_[i], x0, y0, x1, y1) : reachesRectangle(spans_[i], x0, y0, x1, y1);
        if (hit) return true;
      }
    }
  return false;
}

uint64_t ReceiverSet::columnsReached() const {
  if (kind_ == ReceiverKind::Everywhere) return uint64_t(R_) * R_;
  const std::vector<uint8_t> reached = reachedColumns();
  return uint64_t(std::count(reached.begin(), reached.end(), 1));
}

std::vector<uint8_t> ReceiverSet::reachedColumns() const {
  std::vector<uint8_t> reached(size_t(R_) * R_, kind_ == ReceiverKind::Everywhere ? 1 : 0);
  if (kind_ == ReceiverKind::Everywhere) return reached;
  for (const FrustumSpan& s : frustumSpans_)
    for (int64_t y = s.yMin; y <= s.yMax; ++y)
      for (int64_t x = s.xMin; x <= s.xMax; ++x) {
        uint32_t a = 0, b = 0, hints[2] = {0, 0};
        if (frustumReads(s, x, y, a, b, hints) == kReads) reached[size_t(y) * R_ + size_t(x)] = 1;
      }
  for (const Span& s : spans_)
    for (int64_t y = s.yMin; y <= s.yMax; ++y) {
      int64_t x0 = 0, x1 = 0;
      for (uint32_t k = 0; k < s.rings; ++k)
        if (y >= s.ring[k].yMin && y <= s.ring[k].yMax && columnRange(s, s.ring[k], y, x0, x1))
          std::fill_n(reached.begin() + ptrdiff_t(size_t(y) * R_ + size_t(x0)), x1 - x0 + 1, 1);
    }
  return reached;
}

// The columns of row y a ring of the span reaches, [x0, x1]; false when none.
bool ReceiverSet::columnRange(const Span& s, const Ring& r, int64_t y, int64_t& x0, int64_t& x1) {
  double lo = 0, hi = 0;
  ringColumns(ringRows(s, r), y, lo, hi);
  if (!(lo <= hi)) return false;
  x0 = int64_t(lo);
  x1 = int64_t(hi);
  return true;
}

void ReceiverSet::freeIntervals(uint64_t x0, uint64_t y0, uint32_t width, uint32_t height, TexelSlices& slices,
                                bool shareColumns) const {
  if (kind_ == ReceiverKind::Everywhere) return;
  CPVS_CHECK(slices.firstUndefined.size() == size_t(width) * height && slices.firstShadowed.size() == slices.firstUndefined.size());
  const uint32_t bands = (height + kBandRows - 1) / kBandRows;
  tbb::parallel_for(uint32_t(0), bands, [&](uint32_t band) {
    const uint32_t rowBegin = band * kBandRows, rowEnd = std::min(height, rowBegin + kBandRows);
    const size_t texels = size_t(rowEnd - rowBegin) * width;
    const uint32_t* lo = slices.firstUndefined.data() + size_t(rowBegin) * width;
    const uint32_t* hi = slices.firstShadowed.data() + size_t(rowBegin) * width;
    // Each thread's buffers, reused from band to band (the body starts no nested work, so
    // no other band runs on this thread meanwhile): fresh ones cost page faults per band.
    thread_local std::vector<uint32_t> newLo, newHi;
    newLo.resize(texels);
    newHi.resize(texels);
    fillSlices(newLo.data(), texels, 0);
    fillSlices(newHi.data(), texels, R_);
    // The reads [a, b] at texel k: a lit slice needed below the old range, a shadowed
    // one at or behind it.
    auto need = [&](size_t k, uint32_t a, uint32_t b) {
      if (a < lo[k]) newLo[k] = std::max(newLo[k], std::min(b + 1, lo[k]));
      if (b >= hi[k]) newHi[k] = std::min(newHi[k], std::max(a, hi[k]));
    };
    // The spans reaching the band, each once, volume parts together.
    std::vector<uint32_t> items;
    const uint64_t gy0 = y0 + rowBegin, gy1 = y0 + rowEnd - 1, gx1 = x0 + width - 1;
    for (uint64_t cy = gy0 >> log2Cell_; cy <= gy1 >> log2Cell_; ++cy)
      for (uint64_t cx = x0 >> log2Cell_; cx <= gx1 >> log2Cell_; ++cx) {
        const size_t c = size_t(cy * cellsPerSide_ + cx);
        items.insert(items.end(), cellItems_.begin() + cellBegin_[c], cellItems_.begin() + cellBegin_[c + 1]);
      }
    auto partOf = [&](uint32_t i) { return spot_ ? frustumSpans_[i].part : spans_[i].part; };
    std::sort(items.begin(), items.end(), [&](uint32_t a, uint32_t b) {
      return partOf(a) != partOf(b) ? partOf(a) < partOf(b) : a < b;
    });
    items.erase(std::unique(items.begin(), items.end()), items.end());
    // Per column of the band, the hull of one volume part's reads.
    std::vector<uint32_t> hullLo, hullHi;
    // Per column of a span's rows in the band, the slices it reads (columnReads, with the
    // row's part of the plane computed once: the same operations for every tiling).
    const double top = double(R_) - 1;
    auto forColumns = [&](const Span& s, auto&& fn) {
      const int64_t ya = std::max<int64_t>(s.yMin, int64_t(gy0)), yb = std::min<int64_t>(s.yMax, int64_t(gy1));
      if (ya > yb) return;
      // Each ring's columns in each of the span's rows in the band, on vectors of rows.
      double ringX0[kMaxRings][kBandRows], ringX1[kMaxRings][kBandRows];
      for (uint32_t k = 0; k < s.rings; ++k) ringColumnRows(ringRows(s, s.ring[k]), ya, size_t(yb - ya + 1), ringX0[k], ringX1[k]);
      for (int64_t y = ya; y <= yb; ++y) {
        const double cy = double(y) + 0.5;
        // Each ring's columns in the row, cut at their ends into runs that the same
        // rings reach: a run reads the union of their depth ranges.
        int64_t from[kMaxRings], to[kMaxRings];
        double ringLo[kMaxRings], ringHi[kMaxRings];
        uint32_t rings = 0;
        for (uint32_t k = 0; k < s.rings; ++k) {
          const Ring& r = s.ring[k];
          const double lo = ringX0[k][y - ya], hi = ringX1[k][y - ya];
          if (y < r.yMin || y > r.yMax || !(lo <= hi)) continue;
          const int64_t xa = std::max<int64_t>(int64_t(lo), int64_t(x0));
          const int64_t xb = std::min<int64_t>(int64_t(hi), int64_t(gx1));
          if (xa > xb) continue;
          from[rings] = xa, to[rings] = xb, ringLo[rings] = r.loOff, ringHi[rings] = r.hiOff, ++rings;
        }
        if (rings == 0) continue;
        const size_t row = size_t(y - int64_t(gy0)) * width - size_t(x0);
        const double base = s.pz - s.gx * s.px + s.gy * (cy - s.py);
        // The columns [xa, xb] read the depths [loOff, hiOff] about the plane.
        auto emit = [&](int64_t xa, int64_t xb, double loOff, double hiOff) {
          if (xa > xb || !(loOff <= hiOff)) return;
          if (!s.planar) {
            if (!(s.zLo <= s.zHi) || s.zHi < 0) return;
            const uint32_t a = uint32_t(std::min(top, std::max(0.0, s.zLo))), b = uint32_t(std::min(top, s.zHi));
            for (int64_t x = xa; x <= xb; ++x) fn(row + size_t(x), a, b);
            return;
          }
          const PlanarRun run{base, s.gx, s.zLo, s.zHi, loOff, hiOff, top, xa, xb};
          if constexpr (std::is_same_v<std::decay_t<decltype(fn)>, std::decay_t<decltype(need)>>) {
            // The most common run of all: a surface's reads applied at once (receiver_reads.h).
            const size_t at = row + size_t(xa);
            applyPlanarRun(run, lo + at, hi + at, newLo.data() + at, newHi.data() + at);
            return;
          }
          for (int64_t x = xa; x <= xb; ++x) {
            uint32_t a = 0, b = 0;
            if (planarReads(run, x, a, b)) fn(row + size_t(x), a, b);
          }
        };
        ringRuns(from, to, ringLo, ringHi, rings, emit);
      }
    };
    // On a spot grid, each column of a span's reach in the band (frustumReads).
    auto forFrustumColumns = [&](const FrustumSpan& s, auto&& fn) {
      const int64_t ya = std::max<int64_t>(s.yMin, int64_t(gy0)), yb = std::min<int64_t>(s.yMax, int64_t(gy1));
      const int64_t xa = std::max<int64_t>(s.xMin, int64_t(x0)), xb = std::min<int64_t>(s.xMax, int64_t(gx1));
      for (int64_t y = ya; y <= yb; ++y) {
        const size_t row = size_t(y - int64_t(gy0)) * width - size_t(x0);
        forFrustumRow(s, y, xa, xb, [&](int64_t x, uint32_t a, uint32_t b) { fn(row + size_t(x), a, b); });
      }
    };
    auto forSpan = [&](uint32_t i, auto&& fn) {
      if (spot_)
        forFrustumColumns(frustumSpans_[i], fn);
      else
        forColumns(spans_[i], fn);
    };
    auto boundsOf = [&](uint32_t i) {
      return spot_ ? std::array<int64_t, 4>{frustumSpans_[i].xMin, frustumSpans_[i].yMin, frustumSpans_[i].xMax, frustumSpans_[i].yMax}
                   : std::array<int64_t, 4>{spans_[i].xMin, spans_[i].yMin, spans_[i].xMax, spans_[i].yMax};
    };
    for (size_t i = 0; i < items.size();) {
      const uint32_t part = partOf(items[i]);
      size_t j = i;
      while (j < items.size() && partOf(items[j]) == part) ++j;
      if (part == 0) {
        for (size_t k = i; k < j; ++k) forSpan(items[k], need);
      } else {
        // hullLo > hullHi: not read. Only the part's reach in the band is swept.
        if (hullLo.size() < texels) hullLo.resize(texels), hullHi.resize(texels);
        int64_t rx0 = int64_t(gx1), rx1 = int64_t(x0), ry0 = int64_t(gy1), ry1 = int64_t(gy0);
        for (size_t k = i; k < j; ++k) {
          const auto [xMin, yMin, xMax, yMax] = boundsOf(items[k]);
          rx0 = std::min(rx0, std::max(xMin, int64_t(x0))), rx1 = std::max(rx1, std::min(xMax, int64_t(gx1)));
          ry0 = std::min(ry0, std::max(yMin, int64_t(gy0))), ry1 = std::max(ry1, std::min(yMax, int64_t(gy1)));
        }
        auto rect = [&](auto&& fn) {
          for (int64_t y = ry0; y <= ry1; ++y)
            for (int64_t x = rx0; x <= rx1; ++x) fn(size_t(y - int64_t(gy0)) * width + size_t(x - int64_t(x0)));
        };
        rect([&](size_t t) { hullLo[t] = R_, hullHi[t] = 0; });
        for (size_t k = i; k < j; ++k)
          forSpan(items[k], [&](size_t t, uint32_t a, uint32_t b) {
            hullLo[t] = std::min(hullLo[t], a);
            hullHi[t] = std::max(hullHi[t], b);
          });
        rect([&](size_t t) {
          if (hullLo[t] <= hullHi[t]) need(t, hullLo[t], hullHi[t]);
        });
      }
      i = j;
    }
    // An 8x8 column whose texels can share one transition gets it, at the most aligned
    // slice they allow: whole leaves and nodes become homogeneous, and neighbouring
    // columns with overlapping freedom pick the same slice. Written straight into the
    // band's rows of `slices`; per 8 rows, the greatest lo and least hi of each x first
    // (rows are contiguous, so this runs on vectors), then each column's of those 8.
    uint32_t* outLo = slices.firstUndefined.data() + size_t(rowBegin) * width;
    uint32_t* outHi = slices.firstShadowed.data() + size_t(rowBegin) * width;
    const uint32_t rows = rowEnd - rowBegin;
    const uint32_t sharedRows = shareColumns ? rows / 8 * 8 : 0;
    thread_local std::vector<uint32_t> rowLo, rowHi, shared;
    rowLo.resize(width), rowHi.resize(width), shared.resize(width);
    std::fill(shared.begin() + width / 8 * 8, shared.end(), kNoSharedSlice);  // a last part column: as read
    for (uint32_t by = 0; by < sharedRows; by += 8) {
      const uint32_t* lo8 = newLo.data() + size_t(by) * width;
      const uint32_t* hi8 = newHi.data() + size_t(by) * width;
      rowsMaxMin(lo8, hi8, width, 8, width, rowLo.data(), rowHi.data());
      for (uint32_t c = 0; c < width / 8; ++c) {
        uint32_t L = 0, H = R_;
        for (uint32_t x = 8 * c; x < 8 * c + 8; ++x) L = std::max(L, rowLo[x]), H = std::min(H, rowHi[x]);
        uint32_t k = H;
        if (L > H) {
          k = kNoSharedSlice;
        } else if (H < R_) {
          for (int j = 31; j >= 0; --j) {
            const uint32_t aligned = j == 31 ? 0 : (H >> j) << j;
            if (aligned >= L) {
              k = aligned;
              break;
            }
          }
        }
        std::fill_n(shared.begin() + 8 * c, 8, k);
      }
      for (uint32_t y = 0; y < 8; ++y) {
        const size_t at = size_t(by + y) * width;
        selectShared(shared.data(), lo8 + size_t(y) * width, outLo + at, width);
        selectShared(shared.data(), hi8 + size_t(y) * width, outHi + at, width);
      }
    }
    std::copy(newLo.begin() + ptrdiff_t(size_t(sharedRows) * width), newLo.begin() + ptrdiff_t(texels), outLo + size_t(sharedRows) * width);
    std::copy(newHi.begin() + ptrdiff_t(size_t(sharedRows) * width), newHi.begin() + ptrdiff_t(texels), outHi + size_t(sharedRows) * width);
  });
}

}  // namespace cpvs
