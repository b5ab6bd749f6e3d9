#include "cpvs/net/receiver_declaration.h"

#include <google/protobuf/util/json_util.h>

#include <cctype>

#include "cpvs/base/error.h"
#include "cpvs/base/file.h"
#include "cpvs/net/convert.h"
#include "cpvs/scene/boxes.h"

namespace cpvs::net {

ReceiverDeclaration declarationOf(const pb::Receivers& r, const std::function<Scene(const std::string&)>& loadMesh) {
  checkReceivers(r);
  ReceiverDeclaration d;
  d.kind = ReceiverKind(r.kind());
  if (r.max_pcf() != 0) d.maxPcf = int(r.max_pcf());
  setCameras(r, d);
  if (d.kind != ReceiverKind::Volume && d.kind != ReceiverKind::Cameras) return d;
  d.groundLayer = r.ground_layer();
  d.groundLayerFrom = r.ground_layer_from();
  if (r.has_ground_slope_deg()) d.groundSlopeDeg = r.ground_slope_deg();
  if (!r.volume_scene_hash().empty()) d.volume = loadMesh(r.volume_scene_hash());
  for (const pb::ReceiverBox& b : r.boxes()) appendBox(d.volume, fromProto(b.min()), fromProto(b.max()));
  if (d.volume.triangleCount() != 0) finalizeScene(d.volume);
  checkReceiverDeclaration(d);
  return d;
}

void setCameras(const pb::Receivers& r, ReceiverDeclaration& d) {
  d.cameraRegions.clear();
  for (const pb::ReceiverBox& b : r.camera_regions()) d.cameraRegions.push_back({fromProto(b.min()), fromProto(b.max())});
  d.cameraPoints.clear();
  for (const pb::Vec3& p : r.camera_points()) d.cameraPoints.push_back(fromProto(p));
  d.cameraPaths.clear();
  for (const pb::CameraPath& path : r.camera_paths()) {
    d.cameraPaths.emplace_back();
    for (const pb::Vec3& p : path.points()) d.cameraPaths.back().push_back(fromProto(p));
  }
  d.viewDistance = r.view_distance();
  d.cameraVisibility = CameraVisibility(r.camera_visibility());
  d.cameraSpacing = r.camera_spacing();
  d.cameraRays = r.camera_rays();
}

void clearCameras(pb::Receivers& r) {
  r.clear_camera_regions();
  r.clear_camera_points();
  r.clear_camera_paths();
  r.clear_view_distance();
  r.clear_camera_visibility();
  r.clear_camera_spacing();
  r.clear_camera_rays();
}

bool isCameraFile(const std::string& path) {
  if (path.size() < 5) return false;
  std::string end = path.substr(path.size() - 5);
  for (char& c : end) c = char(std::tolower(static_cast<unsigned char>(c)));
  return end == ".json";
}

pb::Receivers readCameraFile(const std::string& path) {
  const std::vector<uint8_t> bytes = readFile(path);
  pb::Receivers r;
  const auto status = google::protobuf::util::JsonStringToMessage(std::string(bytes.begin(), bytes.end()), &r);
  if (!status.ok()) throw InputError(path + ": not a camera file: " + std::string(status.message()));
  pb::Receivers rest = r;
  clearCameras(rest);
  if (rest.ByteSizeLong() != 0)
    throw InputError(path + ": a camera file holds only cameraRegions, cameraPoints, cameraPaths, viewDistance, "
                     "cameraVisibility, cameraSpacing and cameraRays");
  return r;
}

}  // namespace cpvs::net
