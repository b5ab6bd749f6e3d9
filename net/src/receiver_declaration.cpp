#include "cpvs/net/receiver_declaration.h"

#include <google/protobuf/util/json_util.h>

#include <cctype>

#include "cpvs/base/error.h"
#include "cpvs/base/file.h"
#include "cpvs/net/convert.h"
#include "cpvs/net/model_convert.h"
#include "cpvs/scene/boxes.h"

namespace cpvs::net {

ReceiverDeclaration declarationOf(const Receivers& r, const std::function<Scene(const std::string&)>& loadMesh) {
  checkReceivers(toProto(r));
  ReceiverDeclaration d;
  d.kind = r.kind;
  if (r.maxPcf != 0) d.maxPcf = int(r.maxPcf);
  setCameras(r, d);
  if (d.kind != ReceiverKind::Volume && d.kind != ReceiverKind::Cameras) return d;
  d.groundLayer = r.groundLayer;
  d.groundLayerFrom = r.groundLayerFrom;
  if (r.groundSlopeDeg) d.groundSlopeDeg = *r.groundSlopeDeg;
  if (!r.volumeSceneHash.empty()) d.volume = loadMesh(r.volumeSceneHash);
  for (const Box& b : r.boxes) appendBox(d.volume, b.min, b.max);
  if (d.volume.triangleCount() != 0) finalizeScene(d.volume);
  checkReceiverDeclaration(d);
  return d;
}

void setCameras(const Receivers& r, ReceiverDeclaration& d) {
  d.cameraRegions.clear();
  for (const Box& b : r.cameraRegions) d.cameraRegions.push_back({b.min, b.max});
  d.cameraPoints = r.cameraPoints;
  d.cameraPaths = r.cameraPaths;
  d.viewDistance = r.viewDistance;
  d.cameraVisibility = r.cameraVisibility;
  d.cameraSpacing = r.cameraSpacing;
  d.cameraRays = r.cameraRays;
}

void copyCameras(const Receivers& from, Receivers& to) {
  to.cameraRegions = from.cameraRegions;
  to.cameraPoints = from.cameraPoints;
  to.cameraPaths = from.cameraPaths;
  to.viewDistance = from.viewDistance;
  to.cameraVisibility = from.cameraVisibility;
  to.cameraSpacing = from.cameraSpacing;
  to.cameraRays = from.cameraRays;
}

bool isCameraFile(const std::string& path) {
  if (path.size() < 5) return false;
  std::string end = path.substr(path.size() - 5);
  for (char& c : end) c = char(std::tolower(static_cast<unsigned char>(c)));
  return end == ".json";
}

Receivers readCameraFile(const std::string& path) {
  const std::vector<uint8_t> bytes = readFile(path);
  pb::Receivers r;
  const auto status = google::protobuf::util::JsonStringToMessage(std::string(bytes.begin(), bytes.end()), &r);
  if (!status.ok()) throw InputError(path + ": not a camera file: " + std::string(status.message()));
  Receivers cameras, rest;
  try {
    rest = modelOf(r);
  } catch (const InputError& e) {
    throw InputError(path + ": " + e.what());
  }
  copyCameras(rest, cameras);
  copyCameras(Receivers{}, rest);
  if (!(rest == Receivers{}))
    throw InputError(path + ": a camera file holds only cameraRegions, cameraPoints, cameraPaths, viewDistance, "
                     "cameraVisibility, cameraSpacing and cameraRays");
  return cameras;
}

}  // namespace cpvs::net
