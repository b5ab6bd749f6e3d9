#include "coordinator/stored_spec.h"

#include <google/protobuf/util/json_util.h>
#include <google/protobuf/util/message_differencer.h>

#include "cpvs/base/error.h"

namespace cpvs::server {

namespace {

void parseStored(const std::string& json, google::protobuf::Message* m, const std::string& what) {
  // A field a later build removed is no reason to lose the job.
  google::protobuf::util::JsonParseOptions options;
  options.ignore_unknown_fields = true;
  const auto status = google::protobuf::util::JsonStringToMessage(json, m, options);
  if (!status.ok()) throw FormatError(what + " does not parse: " + std::string(status.message()));
}

}  // namespace

std::string storedJson(const google::protobuf::Message& m) {
  std::string out;
  google::protobuf::util::JsonPrintOptions options;
  options.preserve_proto_field_names = true;
  const auto status = google::protobuf::util::MessageToJsonString(m, &out, options);
  if (!status.ok()) throw FormatError("a " + m.GetTypeName() + " has no JSON form: " + std::string(status.message()));
  return out;
}

void storeSpec(JobRecord& j, const pb::BakeSpec& spec) {
  j.spec = storedJson(spec);
  j.receiverScene = spec.options().receivers().volume_scene_hash();
}

void storeSpec(TrackRecord& t, const pb::TrackSpec& spec) {
  t.spec = storedJson(spec);
  t.sceneHash = spec.scene_hash();
  t.receiverScene = spec.options().receivers().volume_scene_hash();
}

pb::BakeSpec bakeSpecOf(const JobRecord& j) {
  pb::BakeSpec spec;
  parseStored(j.spec, &spec, "job " + j.id + ": its stored spec");
  return spec;
}

pb::LightList lightListOf(const JobRecord& j) {
  pb::LightList lights;
  parseStored(j.lights, &lights, "job " + j.id + ": its stored lights");
  return lights;
}

pb::TrackSpec trackSpecOf(const TrackRecord& t) {
  pb::TrackSpec spec;
  parseStored(t.spec, &spec, "track " + t.id + ": its stored spec");
  return spec;
}

bool sameMessage(const google::protobuf::Message& a, const google::protobuf::Message& b) {
  // What the JSON keeps: fields this build does not know (a newer client's) are not
  // stored, so they do not make a retry another request.
  std::unique_ptr<google::protobuf::Message> x(a.New()), y(b.New());
  x->CopyFrom(a);
  y->CopyFrom(b);
  x->DiscardUnknownFields();
  y->DiscardUnknownFields();
  return google::protobuf::util::MessageDifferencer::Equals(*x, *y);
}

SpecRewrite legacySpecRewrite() {
  return {[](JobRecord& j) {
            pb::BakeSpec spec;
            if (!spec.ParseFromString(j.spec)) throw FormatError("job " + j.id + ": its stored spec does not parse");
            storeSpec(j, spec);
            if (j.lights.empty()) return;  // a sun job
            pb::LightList lights;
            if (!lights.ParseFromString(j.lights)) throw FormatError("job " + j.id + ": its stored lights do not parse");
            j.lights = storedJson(lights);
          },
          [](TrackRecord& t) {
            pb::TrackSpec spec;
            if (!spec.ParseFromString(t.spec)) throw FormatError("track " + t.id + ": its stored spec does not parse");
            storeSpec(t, spec);
          }};
}

}  // namespace cpvs::server
