// The accuracy measurements written out: Markdown tables, CSV, and an SVG plot.
#pragma once

#include <string>

#include "cpvs/eval/accuracy.h"

namespace cpvs {

/// Markdown: what was measured and how, then one table row per method and resolution
/// (bytes, bake seconds, binary mismatch overall and per distance bin, PCF 3/5/9 mean
/// and 99th-percentile error, lookup ns per query), the bake stages and the samples per
/// distance bin.
std::string accuracyMarkdown(const AccuracyReport& report);

/// The main table alone (the Markdown one), for printing.
std::string accuracyTable(const AccuracyReport& report);

/// CSV with a header line and one row per method x resolution; rates are fractions,
/// empty fields for a skipped row or an empty bin.
std::string accuracyCsv(const AccuracyReport& report);

/// A hand-written SVG of two panels, binary mismatch rate (log) against bake seconds (log)
/// and against bytes (log), one curve per method, with axes, ticks, labels and a legend.
/// Rates of zero are drawn at the bottom of the axis, marked as such.
std::string accuracySvg(const AccuracyReport& report);

/// Writes accuracy.md, accuracy.csv and accuracy.svg into `dir`, creating it; InputError
/// naming the path when it cannot.
void writeAccuracyReport(const AccuracyReport& report, const std::string& dir);

}  // namespace cpvs
