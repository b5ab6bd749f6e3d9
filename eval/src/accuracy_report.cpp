#include "cpvs/eval/accuracy_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <system_error>

#include "cpvs/bake/stage_times.h"
#include "cpvs/io/cpvs_file.h"

namespace cpvs {

namespace {

std::string format(const char* fmt, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

// "camera at (ex, ey, ez) looking at (tx, ty, tz)", joined by "; " for several.
std::string camerasText(const std::vector<Camera>& cameras) {
  std::string out = cameras.size() == 1 ? "a camera " : std::to_string(cameras.size()) + " cameras: ";
  for (size_t i = 0; i < cameras.size(); ++i) {
    const Camera& c = cameras[i];
    out += (i ? "; " : "") + std::string("at (") + format("%.4g", c.eye.x) + ", " + format("%.4g", c.eye.y) + ", " +
           format("%.4g", c.eye.z) + ") looking at (" + format("%.4g", c.target.x) + ", " + format("%.4g", c.target.y) +
           ", " + format("%.4g", c.target.z) + "), " + format("%.0f", c.fovDeg) + "°";
  }
  return out;
}

// A rate as a percentage with three significant digits; "-" for an empty bin.
std::string percent(double rate) {
  if (std::isnan(rate)) return "-";
  if (rate == 0) return "0";
  return format("%.3g %%", 100.0 * rate);
}

std::string byteSize(uint64_t b) {
  if (b < 1024) return std::to_string(b) + " B";
  const char* units[] = {"KiB", "MiB", "GiB", "TiB"};
  double v = double(b) / 1024.0;
  int u = 0;
  while (v >= 1024.0 && u < 3) {
    v /= 1024.0;
    ++u;
  }
  return format(v >= 100 ? "%.0f" : (v >= 10 ? "%.1f" : "%.2f"), v) + " " + units[u];
}

std::string stage(const AccuracyRow& r, const char* name) {
  auto it = r.stageSeconds.find(name);
  return format("%.3f", it == r.stageSeconds.end() ? 0.0 : it->second);
}

std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string o = "\"";
  for (char c : s) o += c == '"' ? std::string("\"\"") : std::string(1, c);
  return o + "\"";
}

std::string csvNumber(double v) {
  if (std::isnan(v) || std::isinf(v)) return "";
  return format("%.9g", v);
}

std::string xmlText(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '&') o += "&amp;";
    else if (c == '<') o += "&lt;";
    else if (c == '>') o += "&gt;";
    else if (c == '"') o += "&quot;";
    else o += c;
  }
  return o;
}

std::string resolutionCell(const AccuracyRow& r) { return resolutionLabel(r.resolution()); }

}  // namespace

// "≤1 texel | 1–2 | ... | >8 | ": the distance bins as table columns.
std::string binHeader() {
  std::string h;
  for (const auto& b : kDistanceBinNames) h += std::string(b.table) + " | ";
  return h;
}

std::string accuracyTable(const AccuracyReport& rep) {
  std::ostringstream o;
  o << "| method | R | texels a side | bytes | R² map / bytes | bake s | mismatch | " << binHeader()
    << "PCF 3 mean | PCF 3 p99 | PCF 5 mean | PCF 5 p99 | PCF 9 mean | PCF 9 p99 | ns/lookup | ns/lookup PCF 9 |\n";
  o << "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const AccuracyRow& r : rep.rows) {
    o << "| " << accuracyMethodName(r.method) << " | " << resolutionCell(r) << " | ";
    if (r.skipped) {
      o << r.side << " | " << byteSize(r.bytes) << " | " << format("%.2fx", r.ratioToShadowMap()) << " |";
      for (int i = 0; i < 15; ++i) o << (i == 0 ? " skipped |" : " |");
      o << "\n";
      continue;
    }
    o << r.side << " | " << byteSize(r.bytes) << " | " << format("%.2fx", r.ratioToShadowMap()) << " | "
      << format("%.3f", r.bakeSeconds) << " | " << percent(r.mismatchRate());
    for (int b = 0; b < kDistanceBins; ++b) o << " | " << percent(r.binRate(b));
    for (const PcfAccuracy& p : r.pcf) o << " | " << format("%.4f", p.meanAbsError) << " | " << format("%.3f", p.p99AbsError);
    o << " | " << format("%.1f", r.nsPerQuery) << " | " << format("%.1f", r.pcf.back().nsPerQuery) << " |\n";
  }
  return o.str();
}

std::string accuracyMarkdown(const AccuracyReport& rep) {
  std::ostringstream o;
  o << "# Accuracy of CPVS, DAG-MH and shadow maps: " << rep.scene << "\n\n";
  o << "Scene `" << rep.scene << "`, " << rep.triangles << " triangles, light direction ("
    << format("%.4f", rep.lightDir.x) << ", " << format("%.4f", rep.lightDir.y) << ", " << format("%.4f", rep.lightDir.z)
    << "); grid " << format("%.6g", rep.extent) << " × " << format("%.6g", rep.extent) << " × "
    << format("%.6g", rep.depthExtent) << " world units (u × v × depth). " << rep.samples
    << " surface points (" << (rep.cameras.empty() ? "uniform by area" : "seen by " + camerasText(rep.cameras))
    << (rep.receivers == ReceiverKind::Everywhere
            ? std::string()
            : std::string(rep.cameras.empty() ? " over the declared receivers" : "") + "; the CPVS is baked for receivers '" +
                  optionName(rep.receivers) + "' with PCF up to " + std::to_string(rep.receiverPcf))
    << ", seed " << rep.seed << "), the same for every resolution and method; PCF errors on the first "
    << rep.pcfSamples << " of them" << (rep.pcfSamples < rep.samples ? " (a subset, for time)" : "") << ". "
    << rep.threads << " threads; measured in " << format("%.1f", rep.seconds) << " s.\n\n";
  o << accuracyTable(rep) << "\n";
  o << "PCF error against the exact area average of the footprint (" << kAreaRaysPerTexelSide << "×"
    << kAreaRaysPerTexelSide << " stratified shadow rays per footprint texel instead of one at its centre):\n\n"
    << "| method | R | PCF 3 mean | PCF 3 p99 | PCF 5 mean | PCF 5 p99 | PCF 9 mean | PCF 9 p99 |\n"
    << "|---|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const AccuracyRow& r : rep.rows) {
    o << "| " << accuracyMethodName(r.method) << " | " << resolutionCell(r);
    for (const PcfAccuracy& p : r.pcfArea)
      o << " | " << (r.skipped ? std::string(p.width == 3 ? "skipped" : "") : format("%.4f", p.meanAbsError)) << " | "
        << (r.skipped ? std::string() : format("%.3f", p.p99AbsError));
    o << " |\n";
  }
  o << "\n";

  o << "## How it is measured\n\n"
    << (rep.cameras.empty()
            ? "- **Samples**: points uniform by area over the triangles, with the normal of the side a lookup comes "
              "from (outward for closed parts, towards the light for open ones), as `cpvs verify` samples them.\n"
            : "- **Samples**: the first surfaces hit by rays through uniformly random points of the cameras' images "
              "(taken in turn; a ray that sees nothing is drawn again, up to 16 times), with the normal of the side "
              "the camera sees: points spread as a viewer's pixels are.\n")
    << "- **Query point**: the surface point offset along its normal by the CPVS rule (`normalOffsetVoxels`: 1.5 "
       "voxels for binary lookups, 1.5 + (w−1)/2 for PCF w×w, measured in voxel space so that the largest component "
       "moves that many). *CPVS* and *shadow map, full resolution* (side R) share the grid's texels and so the same "
       "point; *shadow map, equal bytes* applies the same rule in its own (larger) texels; *shadow map, equal bytes, "
       "CPVS offset* looks the same map up at the CPVS's point, with a bias made for texels R/side times smaller.\n"
    << "- **DAG-MH**: the shadow map of seed 001 baked for the same receivers (`--format dagmh`): a texel's "
       "depth between the last slice a lookup needs lit and the first it needs shadowed, looked up at the CPVS's "
       "query point; a voxel at or behind the depth is shadowed. It answers every voxel the receivers read as the "
       "CPVS does, so its binary mismatches are the CPVS's but where a query point's voxel straddles a closed part's "
       "surface (undefined: each resolves it its own way, within two texels of a boundary); filters may differ "
       "where a footprint reaches voxels no receiver reads (inside closed geometry).\n"
    << "- **Binary mismatch**: the lookup's answer (lit or shadowed) differs from one exact Embree shadow ray from the "
       "query point towards the light. Query points inside closed geometry (no lookup comes from there) are skipped. "
       "*mismatch* is over all compared samples; the columns ≤1 texel … >8 are the mismatch rate among the samples of "
       "that distance bin (how many fall in each: last table).\n"
    << "- **Distance bins**: the query point's distance across the light (in the u, v plane) to the exact shadow "
       "boundary, in texels of R (extent / R), estimated by probing exact visibility at radii doubling from "
    << format("%.4g", rep.firstRadius) << " (1/16 texel of the finest R) to " << format("%.4g", rep.maxRadius)
    << " (1/16 of the extent), in 12 directions across the light and one towards it, and taking the first radius "
       "where the answer differs: a bin (a, b] holds points whose boundary lies within b texels and, up to the 15° "
       "gap between directions, beyond a. Probes across the light slide along it to stay on the plane through the "
       "query point parallel to its receiver (unless the receiver is within 12° of parallel to the light, which is "
       "then a boundary itself), so that a sloped receiver is not mistaken for a shadow edge; away from the light is "
       "not probed (a lit point meets its own receiver there at the normal offset). Computed once per query point "
       "in world units; each row bins it in its own R's texels.\n"
    << "- **PCF error** (main table): |lookup − exact| where exact is the fraction of the w×w footprint of the "
       "lookup's own texels (around the texel holding its query point) that is lit, one shadow ray from each texel's "
       "centre in u, v at the query point's depth. Mean and 99th percentile over the samples. A shadow map's texel "
       "answers exactly that ray's question (is a surface in front of this depth on the texel's centre line?) up to "
       "its 16-bit depths, so against this reference a shadow map is exact but for depth quantization, and the CPVS "
       "differs only by its depth slices and by how it resolved undefined voxels (inside closed geometry) that a "
       "footprint reaches: it measures what the storage loses, not what the resolution loses. The second table "
       "measures against the area average of the same footprint, which is what resolution loses.\n"
    << "- **Shadow maps**: 16-bit enter depth, quantized as floor((d − d0) / depth range × 65536), one Embree ray per "
       "texel centre (packets of 8) over the grid's u, v extent; a texel shadows a point when the point's quantized "
       "depth is greater than the stored one. *Equal bytes*: side floor(sqrt(DAG bytes / 2)); *full*: side R, "
       "skipped above the byte limit. *Float map, full resolution*: side R, the enter depth itself as a 32-bit float "
       "(R² × 4 bytes: the uncompressed map a DAG-MH stands for), compared with the query point's depth in float; "
       "looked up at the CPVS's query point.\n"
    << "- **CPVS, receivers everywhere**: with receivers declared (`--receivers`), the CPVS baked for every voxel "
       "beside the declared one: its bytes are what the declaration saves; at the declared receivers' points both "
       "answer alike but where a query point's voxel straddles a closed part's surface (undefined for the declared "
       "bake: each resolves it its own way).\n"
    << "- **Bake s**: CPVS: the whole `bakeGrid` (render, masks, insert, compress, merge); DAG-MH: the whole "
       "`bakeDagMh` (render, receivers, hierarchy, compress); shadow map: its rendering.\n"
    << "- **ns/lookup**: a batched lookup (`ShadowQuery::batch`, `ShadowMap::batch`: offset included) over all samples, "
       "repeated for at least " << format("%g", rep.timingSeconds)
    << " s after one untimed run, all threads, divided by the number of queries: ns per query = ms per million "
       "queries. The CPVS-offset row shares the equal-bytes map's lookup.\n\n";

  o << "## Bake stages (seconds)\n\n| R | render | masks | insert | compress | merge | CPVS total | shadow map, "
       "equal bytes | shadow map, full | float map, full |\n|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  for (size_t i = 0; i < rep.rows.size(); ++i) {
    const AccuracyRow& r = rep.rows[i];
    if (r.method != AccuracyMethod::Cpvs) continue;
    o << "| " << resolutionCell(r) << " | " << stage(r, "render") << " | " << stage(r, "masks") << " | "
      << stage(r, "insert") << " | " << stage(r, "compress") << " | " << stage(r, "merge") << " | "
      << format("%.3f", r.bakeSeconds);
    std::string eq = "-", full = "-", floats = "-";
    for (const AccuracyRow& s : rep.rows)
      if (s.log2Resolution == r.log2Resolution) {
        if (s.method == AccuracyMethod::ShadowMapEqualBytes) eq = format("%.3f", s.bakeSeconds);
        if (s.method == AccuracyMethod::ShadowMapFull) full = s.skipped ? "skipped" : format("%.3f", s.bakeSeconds);
        if (s.method == AccuracyMethod::FloatMapFull) floats = s.skipped ? "skipped" : format("%.3f", s.bakeSeconds);
      }
    o << " | " << eq << " | " << full << " | " << floats << " |\n";
  }

  o << "\n## Lookup time (ns per query, batched, " << rep.threads << " threads)\n\n"
    << "| method | R | binary | PCF 3 | PCF 5 | PCF 9 |\n|---|---:|---:|---:|---:|---:|\n";
  for (const AccuracyRow& r : rep.rows) {
    if (r.skipped || r.method == AccuracyMethod::ShadowMapEqualBytesCpvsOffset) continue;
    o << "| " << accuracyMethodName(r.method) << " | " << resolutionCell(r) << " | " << format("%.1f", r.nsPerQuery);
    for (const PcfAccuracy& p : r.pcf) o << " | " << format("%.1f", p.nsPerQuery);
    o << " |\n";
  }

  o << "\n## Samples per distance bin\n\nBins in texels of R; one texel of R is extent / R world units.\n\n"
       "| R | texel (world units) | query point | compared | " << binHeader() << "skipped "
       "(inside closed) |\n|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const AccuracyRow& r : rep.rows) {
    if (r.method != AccuracyMethod::Cpvs && r.method != AccuracyMethod::ShadowMapEqualBytes) continue;
    o << "| " << resolutionCell(r) << " | " << format("%.4g", rep.extent / double(r.resolution())) << " | "
      << (r.method == AccuracyMethod::Cpvs ? "CPVS offset (CPVS, full map, equal bytes CPVS offset)"
                                           : "equal-bytes map's own offset")
      << " | " << r.samples;
    for (int b = 0; b < kDistanceBins; ++b)
      o << " | " << r.binSamples[b] << " (" << format("%.1f", r.samples ? 100.0 * double(r.binSamples[b]) / double(r.samples) : 0.0)
        << " %)";
    o << " | " << r.skippedInside << " |\n";
  }
  for (const AccuracyRow& r : rep.rows)
    if (r.skipped) o << "\n" << accuracyMethodName(r.method) << " at " << resolutionCell(r) << ": " << r.note << ".\n";
  return o.str();
}

std::string accuracyCsv(const AccuracyReport& rep) {
  std::ostringstream o;
  o << "scene,method,resolution,side,texel_world,bytes,ratio_to_shadow_map,skipped,bake_seconds";
  for (const char* s : kBakeGridStages) o << "," << s << "_s";
  o << ",samples,skipped_inside,mismatches,mismatch_rate";
  for (const auto& b : kDistanceBinNames) o << ",samples_" << b.csv << ",mismatch_rate_" << b.csv;
  o << ",pcf_samples";
  for (int w : kAccuracyPcfWidths) o << ",pcf" << w << "_mean_abs_error,pcf" << w << "_p99_abs_error";
  for (int w : kAccuracyPcfWidths) o << ",pcf" << w << "_area_mean_abs_error,pcf" << w << "_area_p99_abs_error";
  o << ",ns_per_query";
  for (int w : kAccuracyPcfWidths) o << ",ns_per_query_pcf" << w;
  o << ",note\n";
  for (const AccuracyRow& r : rep.rows) {
    o << csvField(rep.scene) << "," << accuracyMethodKey(r.method) << "," << r.resolution() << "," << r.side << ","
      << csvNumber(rep.extent / double(r.side)) << "," << r.bytes << "," << csvNumber(r.ratioToShadowMap()) << "," << (r.skipped ? 1 : 0);
    if (r.skipped) {
      const int empty = 1 + int(kBakeGridStages.size()) + 4 + 2 * kDistanceBins + 1 + 4 * int(kAccuracyPcfWidths.size()) + 1 +
                        int(kAccuracyPcfWidths.size());
      for (int i = 0; i < empty; ++i) o << ",";
    } else {
      o << "," << csvNumber(r.bakeSeconds);
      for (const char* s : kBakeGridStages) {
        auto it = r.stageSeconds.find(s);
        o << "," << (it == r.stageSeconds.end() ? std::string() : csvNumber(it->second));
      }
      o << "," << r.samples << "," << r.skippedInside << "," << r.mismatches << "," << csvNumber(r.mismatchRate());
      for (int b = 0; b < kDistanceBins; ++b) o << "," << r.binSamples[b] << "," << csvNumber(r.binRate(b));
      o << "," << r.pcf[0].samples;
      for (const PcfAccuracy& p : r.pcf) o << "," << csvNumber(p.meanAbsError) << "," << csvNumber(p.p99AbsError);
      for (const PcfAccuracy& p : r.pcfArea) o << "," << csvNumber(p.meanAbsError) << "," << csvNumber(p.p99AbsError);
      o << "," << csvNumber(r.nsPerQuery);
      for (const PcfAccuracy& p : r.pcf) o << "," << csvNumber(p.nsPerQuery);
    }
    o << "," << csvField(r.note) << "\n";
  }
  return o.str();
}

namespace {

struct LogAxis {
  double lo = 1, hi = 10;  // decades
  static LogAxis fit(double mn, double mx) {
    LogAxis a;
    if (!(mn > 0) || !(mx > 0)) return a;
    a.lo = std::pow(10.0, std::floor(std::log10(mn) + 1e-9));
    a.hi = std::pow(10.0, std::ceil(std::log10(mx) - 1e-9));
    if (a.hi <= a.lo) a.hi = a.lo * 10;
    return a;
  }
  double frac(double v) const { return (std::log10(v) - std::log10(lo)) / (std::log10(hi) - std::log10(lo)); }
  // Decades, plus 2 and 5 between them when the axis spans few decades.
  std::vector<double> ticks() const {
    std::vector<double> t;
    const bool fine = std::log10(hi / lo) <= 2.5;
    for (double d = lo; d <= hi * 1.0001; d *= 10) {
      t.push_back(d);
      if (fine && d * 10 <= hi * 1.0001) {
        t.push_back(2 * d);
        t.push_back(5 * d);
      }
    }
    return t;
  }
};

std::string tickLabel(double v, int kind) {
  if (kind == 0) return format("%g%%", 100 * v);  // rate, as a percentage
  if (kind == 1) return format("%g s", v);
  // bytes, decimal prefixes on a decimal axis
  const char* units[] = {"B", "kB", "MB", "GB", "TB"};
  int u = 0;
  while (v >= 1000 && u < 4) {
    v /= 1000;
    ++u;
  }
  return format("%.0f", v) + " " + units[u];
}

}  // namespace

std::string accuracySvg(const AccuracyReport& rep) {
  const int W = 1000, H = 490, panelW = 380, panelH = 300, top = 60;
  const int lefts[2] = {90, 580};
  const char* colours[kAccuracyMethods] = {"#1f77b4", "#d62728", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#1f77b4"};
  const char* dashes[kAccuracyMethods] = {"", "", "6,4", "", "", "", "2,3"};

  double rmin = INFINITY, rmax = 0, tmin = INFINITY, tmax = 0, bmin = INFINITY, bmax = 0;
  bool anyZero = false;
  for (const AccuracyRow& r : rep.rows) {
    if (r.skipped || r.samples == 0) continue;
    double rate = r.mismatchRate();
    if (rate > 0) rmin = std::min(rmin, rate), rmax = std::max(rmax, rate);
    else anyZero = true;
    if (r.bakeSeconds > 0) tmin = std::min(tmin, r.bakeSeconds), tmax = std::max(tmax, r.bakeSeconds);
    bmin = std::min(bmin, double(r.bytes));
    bmax = std::max(bmax, double(r.bytes));
  }
  if (!(rmax > 0)) rmin = 1e-4, rmax = 1e-1;
  LogAxis ya = LogAxis::fit(rmin, rmax);
  if (anyZero && ya.lo >= rmin) ya.lo /= 10;  // room below the smallest rate for zeros
  const LogAxis xa[2] = {LogAxis::fit(tmin, tmax), LogAxis::fit(bmin, bmax)};

  std::ostringstream o;
  o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << W << "\" height=\"" << H << "\" viewBox=\"0 0 " << W
    << " " << H << "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  o << "<rect x=\"0\" y=\"0\" width=\"" << W << "\" height=\"" << H << "\" fill=\"white\"/>\n";
  o << "<text x=\"" << W / 2 << "\" y=\"24\" text-anchor=\"middle\" font-size=\"15\">"
    << xmlText("Binary mismatch against exact shadow rays: " + rep.scene + " (" + std::to_string(rep.samples) +
               " surface points)")
    << "</text>\n";
  o << "<text x=\"" << W / 2 << "\" y=\"42\" text-anchor=\"middle\" fill=\"#555\">"
    << xmlText("points along each curve: R = ") ;
  {
    std::string rs;
    for (const AccuracyRow& r : rep.rows)
      if (r.method == AccuracyMethod::Cpvs) rs += (rs.empty() ? "" : ", ") + resolutionLabel(r.resolution());
    o << xmlText(rs + (anyZero ? "; a rate of 0 is drawn on the bottom axis" : "")) << "</text>\n";
  }

  const char* xlabels[2] = {"bake seconds (log scale; shadow maps: rendering)", "bytes (log scale)"};
  for (int p = 0; p < 2; ++p) {
    const int x0 = lefts[p], y0 = top, x1 = x0 + panelW, y1 = top + panelH;
    auto X = [&](double v) { return x0 + xa[p].frac(v) * panelW; };
    auto Y = [&](double v) { return y1 - ya.frac(std::max(v, ya.lo)) * panelH; };
    o << "<g>\n<rect x=\"" << x0 << "\" y=\"" << y0 << "\" width=\"" << panelW << "\" height=\"" << panelH
      << "\" fill=\"none\" stroke=\"#333\"/>\n";
    for (double t : ya.ticks()) {
      const double y = Y(t);
      o << "<line x1=\"" << x0 << "\" y1=\"" << format("%.1f", y) << "\" x2=\"" << x1 << "\" y2=\"" << format("%.1f", y)
        << "\" stroke=\"#ddd\"/>\n";
      o << "<line x1=\"" << x0 - 5 << "\" y1=\"" << format("%.1f", y) << "\" x2=\"" << x0 << "\" y2=\""
        << format("%.1f", y) << "\" stroke=\"#333\"/>\n";
      o << "<text x=\"" << x0 - 8 << "\" y=\"" << format("%.1f", y + 4) << "\" text-anchor=\"end\">"
        << xmlText(tickLabel(t, 0)) << "</text>\n";
    }
    for (double t : xa[p].ticks()) {
      const double x = X(t);
      o << "<line x1=\"" << format("%.1f", x) << "\" y1=\"" << y0 << "\" x2=\"" << format("%.1f", x) << "\" y2=\"" << y1
        << "\" stroke=\"#ddd\"/>\n";
      o << "<line x1=\"" << format("%.1f", x) << "\" y1=\"" << y1 << "\" x2=\"" << format("%.1f", x) << "\" y2=\""
        << y1 + 5 << "\" stroke=\"#333\"/>\n";
      o << "<text x=\"" << format("%.1f", x) << "\" y=\"" << y1 + 19 << "\" text-anchor=\"middle\">"
        << xmlText(tickLabel(t, p == 0 ? 1 : 2)) << "</text>\n";
    }
    o << "<text x=\"" << x0 + panelW / 2 << "\" y=\"" << y1 + 42 << "\" text-anchor=\"middle\">" << xmlText(xlabels[p])
      << "</text>\n";
    o << "<text x=\"" << x0 - 62 << "\" y=\"" << y0 + panelH / 2 << "\" text-anchor=\"middle\" transform=\"rotate(-90 "
      << x0 - 62 << " " << y0 + panelH / 2 << ")\">binary mismatch rate (log scale)</text>\n";
    for (int m = 0; m < kAccuracyMethods; ++m) {
      std::vector<const AccuracyRow*> pts;
      for (const AccuracyRow& r : rep.rows)
        if (int(r.method) == m && !r.skipped && r.samples > 0 && (p == 1 || r.bakeSeconds > 0)) pts.push_back(&r);
      std::sort(pts.begin(), pts.end(), [](auto* a, auto* b) { return a->log2Resolution < b->log2Resolution; });
      if (pts.empty()) continue;
      auto px = [&](const AccuracyRow* r) { return X(p == 0 ? r->bakeSeconds : double(r->bytes)); };
      o << "<polyline fill=\"none\" stroke=\"" << colours[m] << "\" stroke-width=\"2\"";
      if (*dashes[m]) o << " stroke-dasharray=\"" << dashes[m] << "\"";
      o << " points=\"";
      for (const AccuracyRow* r : pts) o << format("%.1f", px(r)) << "," << format("%.1f", Y(r->mismatchRate())) << " ";
      o << "\"/>\n";
      for (const AccuracyRow* r : pts) {
        o << "<circle cx=\"" << format("%.1f", px(r)) << "\" cy=\"" << format("%.1f", Y(r->mismatchRate()))
          << "\" r=\"3.5\" fill=\"" << colours[m] << "\"/>\n";
        if (r->method == AccuracyMethod::Cpvs)
          o << "<text x=\"" << format("%.1f", px(r) + 6) << "\" y=\"" << format("%.1f", Y(r->mismatchRate()) - 6)
            << "\" font-size=\"10\" fill=\"" << colours[m] << "\">" << xmlText(resolutionLabel(r->resolution()))
            << "</text>\n";
      }
    }
    o << "</g>\n";
  }
  // Legend, below the panels, two by two.
  for (int m = 0; m < kAccuracyMethods; ++m) {
    const int lx = 90 + (m % 2) * 420, ly = top + panelH + 68 + (m / 2) * 22;
    o << "<line x1=\"" << lx << "\" y1=\"" << ly << "\" x2=\"" << lx + 28 << "\" y2=\"" << ly << "\" stroke=\""
      << colours[m] << "\" stroke-width=\"2\"" << (*dashes[m] ? std::string(" stroke-dasharray=\"") + dashes[m] + "\"" : "")
      << "/>\n<circle cx=\"" << lx + 14 << "\" cy=\"" << ly << "\" r=\"3.5\" fill=\"" << colours[m] << "\"/>\n";
    o << "<text x=\"" << lx + 34 << "\" y=\"" << ly + 4 << "\">" << xmlText(accuracyMethodName(AccuracyMethod(m)))
      << "</text>\n";
  }
  o << "</svg>\n";
  return o.str();
}

void writeAccuracyReport(const AccuracyReport& report, const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir))
    throw InputError("cannot create output folder " + dir + (ec ? ": " + ec.message() : ": not a folder"));
  auto write = [&](const char* name, const std::string& text) {
    writeFileAtomic((std::filesystem::path(dir) / name).string(), std::vector<uint8_t>(text.begin(), text.end()));
  };
  write("accuracy.md", accuracyMarkdown(report));
  write("accuracy.csv", accuracyCsv(report));
  write("accuracy.svg", accuracySvg(report));
}

}  // namespace cpvs
