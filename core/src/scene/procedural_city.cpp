// makeProceduralCity: a deterministic city of closed boxes on a closed ground slab.
//
// Every box is its own closed part, so the whole city must classify as closed. The
// classifier welds by exact position and counts uses of each undirected edge, so two
// boxes must never share an edge (same two end points): that would make the edge
// non-manifold and both boxes open. The layout rules below guarantee it:
//  - boxes that touch share part of a face, and their extents along the shared face
//    differ at both ends (see touchingPair);
//  - a tower stands strictly inside the top face of its plinth;
//  - a bridge's end faces lie strictly inside the faces of the buildings it joins.
// All coordinates are integers, so they are exact in double and the layout is exact.
#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include "cpvs/scene/procedural_city.h"
#include "cpvs/scene/boxes.h"
#include "cpvs/base/vec3.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/error.h"
#include "cpvs/base/split_mix64.h"

namespace cpvs {
namespace {

constexpr int kBlockSize = 20;    // a city block is kBlockSize x kBlockSize units
constexpr int kStreetWidth = 6;   // between blocks
constexpr int kPitch = kBlockSize + kStreetWidth;
constexpr int kMargin = 10;       // ground around the outer blocks
constexpr int kGroundThickness = 2;
constexpr int kMinHeight = 4;
constexpr int kMaxHeight = 60;

/// An axis-aligned box with integer corners, lo < hi on every axis.
struct Box {
  std::array<int, 3> lo, hi;
};

/// Appends a box as 8 vertices and 12 triangles, counter-clockwise seen from outside
/// (cross(v1 - v0, v2 - v0) points outward).
void appendBox(Scene& scene, const Box& b) {
  cpvs::appendBox(scene, {double(b.lo[0]), double(b.lo[1]), double(b.lo[2])},
                  {double(b.hi[0]), double(b.hi[1]), double(b.hi[2])});
}

/// The boxes of one city block, in world coordinates.
struct Block {
  int x0, z0;  // the block covers [x0, x0 + kBlockSize] x [z0, z0 + kBlockSize]
  std::vector<Box> boxes;
};

/// A building on footprint [x0, x1] x [z0, z1]: either one box, or (sometimes, when the
/// footprint is wide enough) a plinth with a smaller tower standing strictly inside its
/// top face.
void addBuilding(Block& block, SplitMix64& rng, int x0, int x1, int z0, int z1) {
  const bool wide = x1 - x0 >= 6 && z1 - z0 >= 6;
  if (wide && rng.chance(30)) {
    const int plinth = rng.range(kMinHeight, 10);
    const int inset = rng.range(1, std::min(x1 - x0, z1 - z0) / 2 - 2);
    const int tower = rng.range(kMinHeight, kMaxHeight - plinth);
    block.boxes.push_back({{x0, 0, z0}, {x1, plinth, z1}});
    block.boxes.push_back({{x0 + inset, plinth, z0 + inset}, {x1 - inset, plinth + tower, z1 - inset}});
  } else {
    block.boxes.push_back({{x0, 0, z0}, {x1, rng.range(kMinHeight, kMaxHeight), z1}});
  }
}

/// Two buildings touching along the plane x = split inside [x0, x1] x [z0, z1]: the
/// west one keeps z0 and gives up 1-3 units at z1, the east one keeps z1 and gives up
/// 1-3 units at z0. Their z extents therefore differ at both ends, so the two boxes share
/// part of a face but no edge. Needs z1 - z0 >= 8.
void touchingPair(Block& block, SplitMix64& rng, int x0, int x1, int z0, int z1) {
  const int split = rng.range(x0 + 7, x1 - 7);
  addBuilding(block, rng, x0, split, z0, z1 - rng.range(1, 3));
  addBuilding(block, rng, split, x1, z0 + rng.range(1, 3), z1);
}

/// Fills one block with 1-4 buildings in one of four layouts. Footprints reach the
/// block's west and east edges often, which is where bridges attach.
void fillBlock(Block& block, SplitMix64& rng) {
  const int x0 = block.x0, x1 = block.x0 + kBlockSize;
  const int z0 = block.z0, z1 = block.z0 + kBlockSize;
  switch (rng.range(0, 3)) {
    case 0: {  // one building, set back a little from the street
      addBuilding(block, rng, x0 + rng.range(0, 2), x1 - rng.range(0, 2), z0 + rng.range(0, 2),
                  z1 - rng.range(0, 2));
      break;
    }
    case 1: {  // two touching buildings
      touchingPair(block, rng, x0, x1, z0, z1);
      break;
    }
    case 2: {  // two touching buildings, an alley, one more building
      const int alley = z0 + rng.range(10, 13);
      touchingPair(block, rng, x0, x1, z0, alley);
      addBuilding(block, rng, x0 + rng.range(0, 4), x1 - rng.range(0, 4), alley + 1, z1);
      break;
    }
    default: {  // two rows of two touching buildings, separated by an alley
      const int alley = z0 + rng.range(8, 11);
      touchingPair(block, rng, x0, x1, z0, alley);
      touchingPair(block, rng, x0, x1, alley + 1, z1);
      break;
    }
  }
}

/// Tries to join block `west` to block `east` (its neighbour across a street running
/// along z) with a thin bridge. It looks for a box reaching the west block's east edge
/// and a box reaching the east block's west edge that overlap by at least 5 units in z
/// and 10 in height; the bridge's end faces then lie strictly inside both buildings'
/// facing faces. Returns false when no such pair exists.
bool addBridge(const Block& west, const Block& east, SplitMix64& rng, std::vector<Box>& bridges) {
  const int westEdge = west.x0 + kBlockSize;
  const int eastEdge = east.x0;
  for (const Box& a : west.boxes) {
    if (a.hi[0] != westEdge) continue;
    for (const Box& b : east.boxes) {
      if (b.lo[0] != eastEdge) continue;
      const int zlo = std::max(a.lo[2], b.lo[2]), zhi = std::min(a.hi[2], b.hi[2]);
      const int ylo = std::max(a.lo[1], b.lo[1]), yhi = std::min(a.hi[1], b.hi[1]);
      if (zhi - zlo < 5 || yhi - ylo < 10) continue;
      const int width = 3, thickness = 2;
      const int bz = rng.range(zlo + 1, zhi - 1 - width);
      const int by = rng.range(ylo + 4, yhi - 1 - thickness);
      bridges.push_back({{westEdge, by, bz}, {eastEdge, by + thickness, bz + width}});
      return true;
    }
  }
  return false;
}

}  // namespace

Scene makeProceduralCity(int blocks, uint32_t seed) {
  if (blocks < 1 || blocks > 1000)
    throw InputError("makeProceduralCity: blocks must be in [1, 1000], got " + std::to_string(blocks));
  SplitMix64 rng(0x5EED'C17Eull ^ (uint64_t{seed} << 32 | seed));

  std::vector<Block> grid(static_cast<size_t>(blocks) * blocks);
  for (int j = 0; j < blocks; ++j) {
    for (int i = 0; i < blocks; ++i) {
      Block& block = grid[static_cast<size_t>(j) * blocks + i];
      block.x0 = i * kPitch;
      block.z0 = j * kPitch;
      fillBlock(block, rng);
    }
  }

  // About one street crossing in six gets a bridge, where two tall buildings face it.
  std::vector<Box> bridges;
  for (int j = 0; j < blocks; ++j) {
    for (int i = 0; i + 1 < blocks; ++i) {
      if (!rng.chance(17)) continue;
      addBridge(grid[static_cast<size_t>(j) * blocks + i], grid[static_cast<size_t>(j) * blocks + i + 1],
                rng, bridges);
    }
  }

  Scene scene;
  scene.name = "procedural-city";
  const int extent = blocks * kPitch - kStreetWidth;
  appendBox(scene, {{-kMargin, -kGroundThickness, -kMargin}, {extent + kMargin, 0, extent + kMargin}});
  for (const Block& block : grid)
    for (const Box& b : block.boxes) appendBox(scene, b);
  for (const Box& b : bridges) appendBox(scene, b);

  // Street lamps, from their own draws (the geometry's do not change): one candidate per
  // block side on each street, on alternating sidewalks, five in eight kept.
  SplitMix64 lampRng(0x1A3B'5EEDull ^ (uint64_t{seed} << 32 | seed));
  for (int street = 0; street + 1 < blocks; ++street) {
    const double centre = street * kPitch + kBlockSize + kStreetWidth / 2.0;
    for (int along = 0; along < blocks; ++along)
      for (int axis = 0; axis < 2; ++axis) {
        if (!lampRng.chance(62)) continue;
        const double side = (along + axis) % 2 == 0 ? -1 : 1;  // which sidewalk
        const double a = along * kPitch + kBlockSize / 2.0, c = centre + side * (kStreetWidth / 2.0 - 0.5);
        SceneLight lamp;
        lamp.type = SceneLight::Type::Spot;
        lamp.name = "lamp " + std::to_string(scene.lights.size());
        lamp.position = axis == 0 ? Vec3{a, kLampHeight, c} : Vec3{c, kLampHeight, a};
        const Vec3 across = axis == 0 ? Vec3{0, 0, -side} : Vec3{-side, 0, 0};  // towards the street's centre
        lamp.direction = normalize(Vec3{0, -1, 0} + across * 0.25);
        lamp.color = {1, 0.85, 0.6};
        lamp.outerConeDeg = kLampConeDeg;
        lamp.innerConeDeg = kLampConeDeg * 0.75;
        lamp.range = kLampRange;
        scene.lights.push_back(lamp);
      }
  }

  finalizeScene(scene);
  return scene;
}

}  // namespace cpvs
