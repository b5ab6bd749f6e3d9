#include "cpvs/dag/streaming_merger.h"

#include "cpvs/dag/merge.h"

namespace cpvs {

void StreamingMerger::add(Dag&& subDag) {
  stack_.emplace_back(0, std::move(subDag));
  while (stack_.size() >= 2 && stack_[stack_.size() - 1].first == stack_[stack_.size() - 2].first) {
    auto top = std::move(stack_.back());
    stack_.pop_back();
    auto& below = stack_.back();
    below.second = mergeDags(below.second, top.second, mode_);
    below.first += 1;
  }
}

std::optional<Dag> StreamingMerger::finish() {
  if (stack_.empty()) return std::nullopt;
  while (stack_.size() >= 2) {
    auto top = std::move(stack_.back());
    stack_.pop_back();
    stack_.back().second = mergeDags(stack_.back().second, top.second, mode_);
  }
  Dag result = std::move(stack_.back().second);
  stack_.clear();
  return result;
}

uint64_t StreamingMerger::heldBytes() const {
  uint64_t b = 0;
  for (const auto& [rank, dag] : stack_) b += dag.bytes();
  return b;
}

}  // namespace cpvs
