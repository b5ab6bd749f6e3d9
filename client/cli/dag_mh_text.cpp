#include "dag_mh_text.h"

#include <cstdio>
#include <sstream>

#include "cli_util.h"

namespace cpvs::cli {

namespace {

// A row of the table; a negative count leaves its cell empty.
std::string line(const char* label, int64_t count, uint64_t bytes) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "  %-14s %12s %14llu  %s\n", label, count < 0 ? "" : std::to_string(count).c_str(),
                static_cast<unsigned long long>(bytes), humanBytes(bytes).c_str());
  return buf;
}

}  // namespace

std::string dagMhTable(const DagMh& dag) {
  const ValueChunkStats v = valueChunkStats(dag.values);
  const uint64_t side = uint64_t(1) << dag.log2Side, floatMap = side * side * 4;
  std::ostringstream o;
  char buf[200];
  std::snprintf(buf, sizeof buf, "  %-14s %12s %14s\n", "part", "count", "bytes");
  o << buf;
  o << line("inner nodes", int64_t(dag.innerNodeCount()), dag.nodes.size() * 4);
  o << line("treelets", int64_t(dag.treeletCount()), dag.treelets.size() * 4);
  o << line("values", int64_t(v.values), dag.values.bytes());
  o << line("  chunk map", int64_t(dag.values.chunks.size()), dag.values.chunks.size() * sizeof(ValueChunk));
  o << line("  factors", int64_t(v.factors), dag.values.factors.size());
  o << line("skip list", int64_t(dag.skip.size()), dag.skipBytes());
  o << line("total", -1, dag.bytes());
  std::snprintf(buf, sizeof buf,
                "  factors: %.1f %% of the values, %.2f bits on average; %llu stored as raw floats\n",
                v.values ? 100.0 * double(v.factors) / double(v.values) : 0.0,
                v.factors ? double(v.factorBitsTotal) / double(v.factors) : 0.0,
                static_cast<unsigned long long>(v.rawFactors));
  o << buf;
  std::snprintf(buf, sizeof buf, "  32-bit float map of %llu^2: %s, %.1fx larger than the DAG-MH\n",
                static_cast<unsigned long long>(side), humanBytes(floatMap).c_str(),
                double(floatMap) / double(std::max<uint64_t>(1, dag.bytes())));
  o << buf;
  return o.str();
}

std::string dagMhJsonFields(const DmhArtifact& a) {
  const DagMh& dag = a.dag;
  const ValueChunkStats v = valueChunkStats(dag.values);
  const uint64_t side = uint64_t(1) << dag.log2Side;
  std::ostringstream o;
  o << "\"format\": \"dagmh\", \"resolution\": " << side << ", \"receivers\": "
    << jsonString(optionName(a.options.receivers)) << ", \"bytes\": " << dag.bytes() << ", \"inner_nodes\": " << dag.innerNodeCount()
    << ", \"inner_node_bytes\": " << dag.nodes.size() * 4 << ", \"treelets\": " << dag.treeletCount()
    << ", \"treelet_bytes\": " << dag.treelets.size() * 4 << ", \"values\": " << v.values
    << ", \"chunk_map_bytes\": " << dag.values.chunks.size() * sizeof(ValueChunk)
    << ", \"factor_bytes\": " << dag.values.factors.size() << ", \"factors\": " << v.factors
    << ", \"raw_factors\": " << v.rawFactors << ", \"factor_bits_mean\": "
    << jsonNumber(v.factors ? double(v.factorBitsTotal) / double(v.factors) : 0.0)
    << ", \"skip_level\": " << dag.skipLevel << ", \"skip_bytes\": " << dag.skipBytes()
    << ", \"float_map_bytes\": " << side * side * 4;
  return o.str();
}

}  // namespace cpvs::cli
