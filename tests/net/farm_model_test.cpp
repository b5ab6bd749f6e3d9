// The farm model against the contract's messages: every field crosses both ways unchanged
// (absent optional fields stay absent), values the core does not know are refused naming
// their field, and a job file reads back as it was written.
#include <google/protobuf/util/message_differencer.h>
#include <gtest/gtest.h>

#include "cpvs/base/error.h"
#include "cpvs/net/convert.h"
#include "cpvs/net/farm_model.h"
#include "cpvs/net/model_convert.h"

namespace cpvs::net {
namespace {

using google::protobuf::util::MessageDifferencer;

pb::Vec3 v3(double x, double y, double z) { return toProto(Vec3{x, y, z}); }

/// A receiver declaration with every field set to something other than its default.
pb::Receivers everyReceiverField() {
  pb::Receivers r;
  r.set_kind(pb::RECEIVERS_CAMERAS);
  r.set_max_pcf(5);
  r.set_volume_scene_hash(std::string(32, 'd'));
  pb::ReceiverBox& box = *r.add_boxes();
  *box.mutable_min() = v3(-1, 0, -1);
  *box.mutable_max() = v3(1, 2, 1);
  pb::ReceiverBox& region = *r.add_camera_regions();
  *region.mutable_min() = v3(0, 1, 0);
  *region.mutable_max() = v3(4, 2, 4);
  r.set_view_distance(7.5);
  *r.add_camera_points() = v3(1, 1.5, 1);
  pb::CameraPath& path = *r.add_camera_paths();
  *path.add_points() = v3(0, 1, 0);
  *path.add_points() = v3(3, 1, 3);
  r.set_camera_visibility(pb::CAMERA_VISIBILITY_SAMPLED);
  r.set_camera_spacing(0.25);
  r.set_camera_rays(64);
  r.set_ground_layer(2);
  r.set_ground_slope_deg(30);
  r.set_ground_layer_from(0.5);
  return r;
}

/// A spec with every field set as the model writes it back (a light's colour and
/// intensity present, a spot light's direction, an area light's resolution in texels).
pb::BakeSpec everySpecField() {
  pb::BakeSpec s;
  s.set_scene_hash(std::string(32, 'a'));
  s.set_resolution("4K");
  pb::BakeOptions& o = *s.mutable_options();
  o.set_closed(pb::CLOSED_OFF);
  o.set_exit(pb::EXIT_APPROX);
  o.set_no_cull(true);
  o.set_compress(pb::COMPRESS_BOTTOMUP);
  o.set_undefined_rule(pb::UNDEFINED_OLD);
  o.set_tile_size(512);
  o.set_depth_slices(1024);
  o.set_renderer(pb::RENDERER_EMBREE);
  *o.mutable_receivers() = everyReceiverField();
  s.set_priority(-7);
  s.set_name("every field");
  pb::Light& spot = *s.add_lights();
  spot.set_kind(pb::LIGHT_SPOT);
  spot.set_name("lamp");
  *spot.mutable_position() = v3(1, 5, 2);
  *spot.mutable_direction() = v3(0, -1, 0.1);
  spot.set_cone_deg(35);
  spot.set_range(40);
  *spot.mutable_colour() = v3(1, 0.8, 0.6);
  spot.set_intensity(3);
  spot.set_near(0.2);
  spot.set_resolution("512");
  spot.add_exclude("shade");
  pb::Light& point = *s.add_lights();
  point.set_kind(pb::LIGHT_POINT);
  *point.mutable_position() = v3(-3, 4, 0);
  *point.mutable_colour() = v3(1, 1, 1);
  point.set_intensity(1);
  s.set_scene_lights(true);
  s.set_footprint(0.125);
  s.set_pointer_grid(3);
  pb::Medium& fog = *s.add_media();
  fog.set_name("fog");
  fog.set_scattering(0.02);
  fog.set_absorption(0.01);
  fog.set_g(0.3);
  pb::AreaLight& panel = *s.add_area_lights();
  panel.set_name("panel");
  *panel.mutable_centre() = v3(0, 3, 0);
  *panel.mutable_edge_u() = v3(1, 0, 0);
  *panel.mutable_edge_v() = v3(0, 0, 1);
  panel.set_vpls(16);
  panel.set_resolution("64");
  panel.set_seed(99);
  *panel.mutable_colour() = v3(0.9, 0.9, 1);
  panel.set_intensity(5);
  panel.set_range(12);
  return s;
}

TEST(FarmModel, ASpecCrossesBothWaysUnchanged) {
  const pb::BakeSpec full = everySpecField();
  const BakeSpec model = modelOf(full);
  EXPECT_EQ(model.options.tileSize, 512u);
  EXPECT_EQ(model.options.depthSlices, 1024u);
  ASSERT_TRUE(model.options.receivers);
  EXPECT_EQ(model.options.receivers->cameraPaths.size(), 1u);
  EXPECT_EQ(model.options.receivers->groundSlopeDeg, 30.0);
  ASSERT_EQ(model.lights.size(), 2u);
  EXPECT_EQ(model.lights[0].log2Resolution, 9);
  EXPECT_EQ(model.lights[0].exclude, std::vector<std::string>{"shade"});
  ASSERT_EQ(model.areaLights.size(), 1u);
  EXPECT_EQ(model.areaLights[0].seed, 99u);
  EXPECT_EQ(model.pointerGrid, 3u);
  EXPECT_TRUE(MessageDifferencer::Equals(toProto(model), full)) << toProto(model).DebugString();

  // Sun angles, and absent options stay absent (no renderer, no receivers, no pointer grid).
  pb::BakeSpec sun;
  sun.set_scene_hash(std::string(32, 'b'));
  sun.mutable_sun_angles()->set_elevation_deg(40);
  sun.mutable_sun_angles()->set_azimuth_deg(120);
  sun.set_resolution("1024");
  const BakeSpec sunModel = modelOf(sun);
  ASSERT_TRUE(std::holds_alternative<SunAngles>(sunModel.sun));
  EXPECT_EQ(std::get<SunAngles>(sunModel.sun).azimuthDeg, 120);
  EXPECT_FALSE(sunModel.options.renderer);
  EXPECT_FALSE(sunModel.options.receivers);
  const pb::BakeSpec back = toProto(sunModel);
  pb::BakeSpec sunAsNew = sun;
  sunAsNew.mutable_options()->set_undefined_rule(pb::UNDEFINED_NEW);
  EXPECT_TRUE(MessageDifferencer::Equals(back, sunAsNew)) << back.DebugString();
  EXPECT_FALSE(back.options().has_renderer());
  // A spec without an undefined rule comes from a client older than the aligned rule,
  // which could not send new (the zero value): it means new, and says so on its way back.
  EXPECT_EQ(sunModel.options.undefinedRule, UndefinedRule::New);
  EXPECT_TRUE(back.options().has_undefined_rule());
  EXPECT_EQ(back.options().undefined_rule(), pb::UNDEFINED_NEW);
  EXPECT_EQ(JobOptions{}.undefinedRule, UndefinedRule::Aligned);
  EXPECT_FALSE(back.options().has_receivers());
  EXPECT_FALSE(back.has_pointer_grid());
}

TEST(FarmModel, ATrackSpecCrossesBothWaysForEveryPath) {
  pb::TrackSpec t;
  t.set_scene_hash(std::string(32, 'c'));
  t.set_resolution("2K");
  *t.mutable_options()->mutable_receivers() = everyReceiverField();
  t.mutable_options()->set_undefined_rule(pb::UNDEFINED_ALIGNED);  // the model always names it
  t.set_name("day");
  t.set_keyframes_ahead(3);
  t.set_keep_versions(5);
  pb::PlacePath place;
  place.set_latitude_deg(39.7);
  place.set_longitude_deg(-105.2);
  place.set_height_m(1800);
  place.set_start_utc("2024-06-21T10:00:00-06:00");
  place.set_end_utc("2024-06-21T13:00:00-06:00");
  place.set_step_seconds(1800);
  place.set_up("+z");
  place.set_north("+y");
  *t.mutable_place() = place;
  EXPECT_TRUE(MessageDifferencer::Equals(toProto(modelOf(t)), t));
  *t.mutable_clock()->mutable_place() = place;
  t.mutable_clock()->set_rate(60);
  ASSERT_TRUE(std::holds_alternative<ClockPath>(modelOf(t).path));
  EXPECT_TRUE(MessageDifferencer::Equals(toProto(modelOf(t)), t));
  *t.mutable_directions()->add_directions() = v3(0.3, -1, 0.2);
  *t.mutable_directions()->add_directions() = v3(-0.3, -1, 0.2);
  ASSERT_EQ(std::get<std::vector<Vec3>>(modelOf(t).path).size(), 2u);
  EXPECT_TRUE(MessageDifferencer::Equals(toProto(modelOf(t)), t));
}

TEST(FarmModel, ValuesTheCoreDoesNotKnowAreRefusedNamingTheField) {
  auto refusal = [](const pb::BakeSpec& s) {
    try {
      (void)modelOf(s);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  pb::BakeSpec s = everySpecField();
  s.mutable_options()->set_closed(pb::ClosedMode(7));
  EXPECT_EQ(refusal(s), "options.closed: unknown value 7");
  s = everySpecField();
  s.mutable_options()->set_renderer(pb::Renderer(5));
  EXPECT_EQ(refusal(s), "options.renderer: unknown value 5");
  s = everySpecField();
  s.mutable_options()->mutable_receivers()->set_kind(pb::ReceiverKind(9));
  EXPECT_EQ(refusal(s), "options.receivers.kind: unknown value 9");
  s = everySpecField();
  s.mutable_options()->mutable_receivers()->set_camera_visibility(pb::CameraVisibility(4));
  EXPECT_EQ(refusal(s), "options.receivers.camera_visibility: unknown value 4");
  // What the model cannot hold: a spot light without its axis.
  s = everySpecField();
  s.mutable_lights(0)->clear_direction();
  EXPECT_EQ(refusal(s), "lights[0]: a spot light needs a direction");
  s = everySpecField();
  s.mutable_lights(1)->set_kind(pb::LightKind(3));
  EXPECT_EQ(refusal(s), "lights[1]: light kind 3 is unknown");
  // A status from a newer coordinator: an unknown state is unspecified, not a crash.
  pb::JobStatus status;
  status.set_state(pb::JobState(42));
  EXPECT_EQ(modelOf(status).state, JobState::Unspecified);
}

TEST(FarmModel, AJobFileReadsBackAsItWasWritten) {
  const BakeSpec model = modelOf(everySpecField());
  const std::string json = toJson(model);
  EXPECT_NE(json.find("\"scene_hash\""), std::string::npos) << json;  // the contract's names
  const BakeSpec read = bakeSpecFromJson(json, "job.json");
  EXPECT_TRUE(MessageDifferencer::Equals(toProto(read), toProto(model)));
  try {
    (void)bakeSpecFromJson("{\"options\": {\"closed\": 7}}", "bad.json");
    ADD_FAILURE() << "an unknown option value was read";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "bad.json: options.closed: unknown value 7");
  }
  EXPECT_THROW((void)bakeSpecFromJson("{\"no_such_field\": 1}", "bad.json"), InputError);
  // A job file without an undefined rule takes this version's default; one naming new, new.
  EXPECT_EQ(bakeSpecFromJson("{\"resolution\": \"1024\"}", "j.json").options.undefinedRule, UndefinedRule::Aligned);
  EXPECT_EQ(bakeSpecFromJson("{\"options\": {\"undefined_rule\": \"UNDEFINED_NEW\"}}", "j.json").options.undefinedRule,
            UndefinedRule::New);
}

TEST(FarmModel, StatusesAndStates) {
  pb::JobStatus p;
  p.set_job_id("j1");
  p.set_state(pb::JOB_MERGING);
  p.set_tiles_total(16);
  p.set_tiles_done(9);
  p.set_eta_seconds(-1);
  pb::StageSeconds& st = *p.add_stages();
  st.set_stage("render");
  st.set_seconds(2.5);
  *p.mutable_spec() = everySpecField();
  const JobStatus s = modelOf(p);
  EXPECT_EQ(s.jobId, "j1");
  EXPECT_EQ(s.state, JobState::Merging);
  EXPECT_EQ(s.tilesDone, 9u);
  EXPECT_LT(s.etaSeconds, 0);
  ASSERT_EQ(s.stages.size(), 1u);
  EXPECT_EQ(s.stages[0].stage, "render");
  EXPECT_EQ(s.spec.name, "every field");
  EXPECT_STREQ(jobStateName(JobState::Merging), "merging");
  EXPECT_STREQ(jobStateName(JobState(42)), "unknown");
  EXPECT_FALSE(isFinalState(JobState::Merging));
  EXPECT_TRUE(isFinalState(JobState::Cancelled));
  EXPECT_STREQ(trackStateName(TrackState::Finished), "finished");

  pb::TrackVersion v;
  v.set_sequence(4);
  v.set_instant_unix_ms(1700000000000);
  *v.mutable_sun_direction() = v3(0, -1, 0);
  v.set_checksum(std::string(32, 'e'));
  const TrackVersion m = modelOf(v);
  EXPECT_EQ(m.sequence, 4u);
  EXPECT_EQ(m.instantUnixMs, 1700000000000);
  EXPECT_EQ(m.sunDirection.y, -1);
}

}  // namespace
}  // namespace cpvs::net
