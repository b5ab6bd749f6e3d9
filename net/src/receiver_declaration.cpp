#include "cpvs/net/receiver_declaration.h"

#include "cpvs/net/convert.h"
#include "cpvs/scene/boxes.h"

namespace cpvs::net {

ReceiverDeclaration declarationOf(const pb::Receivers& r, const std::function<Scene(const std::string&)>& loadMesh) {
  checkReceivers(r);
  ReceiverDeclaration d;
  d.kind = ReceiverKind(r.kind());
  if (r.max_pcf() != 0) d.maxPcf = int(r.max_pcf());
  if (d.kind != ReceiverKind::Volume) return d;
  if (!r.volume_scene_hash().empty()) d.volume = loadMesh(r.volume_scene_hash());
  for (const pb::ReceiverBox& b : r.boxes()) appendBox(d.volume, fromProto(b.min()), fromProto(b.max()));
  finalizeScene(d.volume);
  checkReceiverDeclaration(d);
  return d;
}

}  // namespace cpvs::net
