#include "cpvs/net/receiver_declaration.h"

#include "cpvs/net/convert.h"
#include "cpvs/scene/boxes.h"

namespace cpvs::net {

ReceiverDeclaration declarationOf(const pb::Receivers& r, const std::function<Scene(const std::string&)>& loadMesh) {
  checkReceivers(r);
  ReceiverDeclaration d;
  d.kind = ReceiverKind(r.kind());
  if (r.max_pcf() != 0) d.maxPcf = int(r.max_pcf());
  for (const pb::ReceiverBox& b : r.camera_regions()) d.cameraRegions.push_back({fromProto(b.min()), fromProto(b.max())});
  d.viewDistance = r.view_distance();
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

}  // namespace cpvs::net
