// How a job's and a track's specs are kept in the store: each message one JSON document
// in protobuf's JSON mapping (field names as in farm.proto), readable with any SQLite
// shell and stable across protobuf versions, and the scenes they name in columns of
// their own. What parses them back, and the rewrite of a store that kept them as
// serialized protobuf (schema 10 and older).
#pragma once

#include <google/protobuf/message.h>

#include <string>

#include "cpvs/v1/farm.pb.h"
#include "store/farm_store.h"

namespace cpvs::server {

namespace pb = ::cpvs::v1;

/// `m` as the store keeps it: one line of JSON.
std::string storedJson(const google::protobuf::Message& m);

/// A job's spec, with the receiver volume's scene column it fills.
void storeSpec(JobRecord& j, const pb::BakeSpec& spec);
/// A track's spec, with its scene column.
void storeSpec(TrackRecord& t, const pb::TrackSpec& spec);

/// The stored messages; FormatError naming the job or track when one does not parse (a
/// damaged store).
pb::BakeSpec bakeSpecOf(const JobRecord& j);
pb::LightList lightListOf(const JobRecord& j);
pb::TrackSpec trackSpecOf(const TrackRecord& t);

/// Whether two messages say the same (a retried request against the stored one).
bool sameMessage(const google::protobuf::Message& a, const google::protobuf::Message& b);

/// Rewrites specs kept as serialized protobuf into JSON, filling the scene columns.
SpecRewrite legacySpecRewrite();

}  // namespace cpvs::server
