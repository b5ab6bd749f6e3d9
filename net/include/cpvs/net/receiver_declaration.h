// A farm job's receivers as the bake takes them: what the coordinator and the worker
// both build from a job's options, so that both free the same voxels as a local bake.
#pragma once

#include <functional>
#include <string>

#include "cpvs/bake/receivers.h"
#include "cpvs/net/farm_model.h"

namespace cpvs::net {

/// The declaration of `receivers` (checkReceivers first, convert.h): its kind and PCF
/// width, and for a volume the mesh `loadMesh(volumeSceneHash)` returns followed by the
/// boxes, in order, as `cpvs bake --receivers volume:MESH --receiver-box ...` builds it (the same
/// receiverHash). InputError for an invalid or open volume.
ReceiverDeclaration declarationOf(const Receivers& receivers,
                                  const std::function<Scene(const std::string& hash)>& loadMesh);

/// Whether the file `cameras:FILE` names is a camera file (it ends in .json, any case) rather than a
/// volume mesh.
bool isCameraFile(const std::string& path);

/// A camera file: the camera fields of a job's receivers in proto JSON (cameraRegions,
/// cameraPoints, cameraPaths, viewDistance, cameraVisibility, cameraSpacing, cameraRays),
/// the same text a job file's "receivers" holds. InputError naming the file for anything
/// unreadable, malformed or not a camera field.
Receivers readCameraFile(const std::string& path);

/// Replaces the camera fields of `to` (those a camera file holds) with those of `from`.
void copyCameras(const Receivers& from, Receivers& to);

/// Sets the camera fields of `declaration` from those of `receivers`.
void setCameras(const Receivers& receivers, ReceiverDeclaration& declaration);

}  // namespace cpvs::net
