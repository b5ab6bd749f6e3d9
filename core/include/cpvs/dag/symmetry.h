// Subtrees equal up to a reflection or an inversion: how many distinct nodes a DAG would
// keep if a reference could name a node reflected along x, y or z and/or with lit and
// shadowed swapped (SSVDAGs, Jaspe-Villanueva et al., i3D 2016, add the reflections; a
// shadow volume's two sides of a step are each other's inversion). The census that
// decides whether such references pay, per scene, before any format carries them.
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/dag/dag.h"

namespace cpvs {

/// The generators of the transforms: one bit each, and a transform is any combination
/// (the group Z2^4: every element is its own inverse and they commute).
enum SymmetryBit : uint32_t {
  kReflectX = 1,    // x -> size - 1 - x (a leaf's columns)
  kReflectY = 2,    // y -> size - 1 - y (a leaf's rows)
  kReflectZ = 4,    // z -> size - 1 - z (a level-0 node's slices; a leaf is one slice)
  kInvert = 8,      // lit <-> shadowed
};
constexpr uint32_t kAllSymmetries = kReflectX | kReflectY | kReflectZ | kInvert;

/// A leaf mask under transform t (kReflectZ leaves a one-slice leaf as it is).
uint64_t transformLeaf(uint64_t mask, uint32_t t);

/// Per level (index 0: leaves, l + 1: internal level l): the nodes of the DAG, and the
/// classes they fall into when nodes equal under a transform of `generators` are one.
struct SymmetryCensus {
  uint32_t generators = 0;
  std::vector<uint64_t> nodes;
  std::vector<uint64_t> classes;
  /// Node data of today's packed layout (Dag::bytes), and an estimate of the same layout
  /// keeping one node per class: references as wide as today's rule gives for the classes
  /// below, and the transforms other than the identity (popcount(generators) bits each,
  /// marked by the unused child code 3) in as many half-words as they fill after them.
  uint64_t plainBytes = 0;
  uint64_t symmetricBytes = 0;
};

/// The census of a DAG whose levels are free of duplicates (compressed or merged).
SymmetryCensus symmetryCensus(const Dag& dag, uint32_t generators);

}  // namespace cpvs
