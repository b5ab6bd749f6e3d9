// The farm model (farm_model.h) to the contract's messages and back: what the client
// library sends and reads, and what the coordinator takes at its boundary. Field for
// field; enum values are checked on the way in (InputError naming the field), the rest is
// the job service's to check.
#pragma once

#include "cpvs/net/farm_model.h"
#include "cpvs/v1/farm.pb.h"

namespace cpvs::net {

namespace pb = ::cpvs::v1;

pb::Receivers toProto(const Receivers& r);
Receivers modelOf(const pb::Receivers& r);

pb::BakeOptions toProto(const JobOptions& o);
JobOptions modelOf(const pb::BakeOptions& o);

/// InputError also for a spot light without a direction, which the model cannot hold.
pb::BakeSpec toProto(const BakeSpec& s);
BakeSpec modelOf(const pb::BakeSpec& s);

JobStatus modelOf(const pb::JobStatus& s);

pb::TrackSpec toProto(const TrackSpec& s);
TrackSpec modelOf(const pb::TrackSpec& s);
TrackStatus modelOf(const pb::TrackStatus& s);
TrackVersion modelOf(const pb::TrackVersion& v);

}  // namespace cpvs::net
