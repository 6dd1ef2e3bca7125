#include "rest_schemas.hpp"

#include <nlohmann/json.hpp>

#include "core/bundle.hpp"

namespace lw::server::rest::schemas {
namespace {

using nlohmann::ordered_json;

std::string Ref(const char* name) {
  return std::string(R"j({"$ref":"#/components/schemas/)j") + name + "\"}";
}

/// The alarm rules as core::AlarmConfigJson writes them, from the rule table itself: each rule an
/// object of exactly its settings (`all`: every setting present, as the server answers; else any,
/// as a change names them).
std::string AlarmRulesSchema(bool all) {
  ordered_json rules = {{"type", "object"}, {"additionalProperties", false}, {"properties", ordered_json::object()}};
  if (all) rules["required"] = ordered_json::array();
  for (const core::AlarmRuleSpec& spec : core::AlarmRuleSpecs()) {
    ordered_json settings = {{"enabled", {{"type", "boolean"}}},
                             {"severity", {{"type", "string"}, {"enum", {"info", "warning", "critical"}}}}};
    ordered_json required = {"enabled", "severity"};
    for (const char* key : {spec.threshold_key, spec.hysteresis_key}) {
      if (!key) continue;
      settings[key] = {{"type", "number"}, {"minimum", 0}, {"maximum", spec.max}};
      required.push_back(key);
    }
    ordered_json rule = {{"type", "object"}, {"additionalProperties", false}, {"properties", settings}};
    if (all) {
      rule["required"] = required;
      rules["required"].push_back(spec.name);
    }
    rules["properties"][spec.name] = rule;
  }
  if (!all) return rules.dump();
  return ordered_json{{"type", "object"}, {"required", {"rules"}}, {"properties", {{"rules", rules}}}}.dump();
}

}  // namespace

const std::vector<std::pair<const char*, std::string>>& SharedSchemas() {
  static const std::vector<std::pair<const char*, std::string>> shared = {
      {"Error", R"j({"type":"object","required":["error"],"properties":{"error":{"type":"string"}}})j"},
      // A liner row as crusher.json names it.
      {"Row",
       R"j({"type":"object","required":["name","z_min_m","z_max_m"],"properties":{"name":{"type":"string"},
           "z_min_m":{"type":"number"},"z_max_m":{"type":"number"}}})j"},
      // A stored reading (GET .../sensors, .../readings); previous_liner only when it is a previous liner's.
      {"StoredReading",
       R"j({"type":"object","required":["time","seq","thickness_mm","loops_intact","flags","battery_mv","received"],
           "properties":{"time":{"type":"string","format":"date-time"},"seq":{"type":"integer","minimum":0},
           "thickness_mm":{"type":"number"},"loops_intact":{"type":"integer"},"flags":{"type":"integer"},
           "battery_mv":{"type":"integer"},"received":{"type":"string","format":"date-time"},
           "previous_liner":{"type":"boolean","enum":[true]}}})j"},
      // The reading each sensor contributed to a wear or forecast result.
      {"ReadingUsed",
       R"j({"type":"object","required":["sensor","seq","time","thickness_mm"],"properties":{"sensor":{"type":"string"},
           "seq":{"type":"integer"},"time":{"type":"string","format":"date-time"},"thickness_mm":{"type":"number"}}})j"},
      // core::ThinnestAreaJson: numbers are null where the data support none.
      {"ThinnestArea",
       R"j({"type":"object","required":["thickness_mm","band_mm","patch_m","z_m","theta_deg","shape","supported",
           "extrapolated","nearest_sensor_m","row","whole_row","worn_through","half_width_mm","band_parts_mm","detail"],
           "properties":{"thickness_mm":{"type":"number","nullable":true},
           "band_mm":{"type":"array","minItems":2,"maxItems":2,"items":{"type":"number","nullable":true}},
           "patch_m":{"type":"number","nullable":true},"z_m":{"type":"number","nullable":true},
           "theta_deg":{"type":"number","nullable":true,"description":"null unless shape is square"},
           "shape":{"type":"string","enum":["square","ring","row"]},"supported":{"type":"boolean"},
           "extrapolated":{"type":"boolean"},"nearest_sensor_m":{"type":"number","nullable":true},
           "row":{"type":"string"},"whole_row":{"type":"boolean"},"worn_through":{"type":"boolean"},
           "half_width_mm":{"type":"number","nullable":true},
           "band_parts_mm":{"type":"object","required":["row_scale_sd","map_sd"],"properties":{
             "row_scale_sd":{"type":"number","nullable":true},"map_sd":{"type":"number","nullable":true}}},
           "detail":{"type":"string"},
           "sensor_fallback":{"type":"object","required":["sensor","thickness_mm","thickness_interval_mm","time"],
             "properties":{"sensor":{"type":"string"},"thickness_mm":{"type":"number"},
             "thickness_interval_mm":{"type":"array","minItems":2,"maxItems":2,"items":{"type":"number"}},
             "time":{"type":"string","format":"date-time"}}}}})j"},
      // estimate::ScanJson: the scan the wear is corrected by (applied) or why not (detail).
      {"Scan",
       R"j({"type":"object","nullable":true,"required":["file","date","points_used","points_total","applied"],
           "properties":{"file":{"type":"string"},"date":{"type":"string","format":"date-time"},
           "points_used":{"type":"integer"},"points_total":{"type":"integer"},"applied":{"type":"boolean"},
           "faces_corrected":{"type":"integer"},"faces_filled":{"type":"integer"},
           "median_ratio":{"type":"number","nullable":true},"map_model_error_relative":{"type":"number","nullable":true},
           "detail":{"type":"string"},"prior_campaign":{"type":"string"},
           "pattern_change_relative":{"type":"number","nullable":true},
           "sensors_spread_prior_relative":{"type":"number","nullable":true},
           "sensors_spread_map_relative":{"type":"number","nullable":true},"sensors_compared":{"type":"integer"}}})j"},
      // A number per sensor id (a diagnosis' predictions).
      {"SensorValues",
       R"j({"type":"object","required":["sensors"],"properties":{"sensors":{"type":"object",
           "additionalProperties":{"type":"number"}}}})j"},
      // GET /healthz (200 ok, 503 degraded: the same body).
      {"Health",
       R"j({"type":"object","required":["status","version","db"],"properties":{
           "status":{"type":"string","enum":["ok","degraded"]},"version":{"type":"string"},
           "db":{"type":"string","description":"ok, or why the database cannot be read"},
           "reason":{"type":"string","description":"why degraded (disk full, read-only file system)"},
           "broker":{"type":"string","description":"connected, disconnected, or why the server does not subscribe"},
           "readings_stored":{"type":"integer"},"duplicates":{"type":"integer"},"rejected":{"type":"integer"},
           "held":{"type":"integer"},"crusher_errors":{"type":"array","items":{"type":"string"}},
           "startup":{"type":"object","required":["crushers","loaded","computed","done"],"properties":{
             "crushers":{"type":"integer"},"loaded":{"type":"integer"},"computed":{"type":"integer"},
             "done":{"type":"boolean"}}}}})j"},
      // POST .../readings: what the batch did.
      {"IngestResult",
       R"j({"type":"object","required":["stored","duplicates","conflicts","rejected","held","errors"],"properties":{
           "stored":{"type":"integer","minimum":0},"duplicates":{"type":"integer","minimum":0},
           "conflicts":{"type":"integer","minimum":0},"rejected":{"type":"integer","minimum":0},
           "held":{"type":"integer","minimum":0,"description":"dated ahead of the server's clock: post again later"},
           "errors":{"type":"array","items":{"type":"string"},"description":"one line per rejection or conflict"},
           "error":{"type":"string","description":"only when no reading was taken (422)"}}})j"},
  };
  return shared;
}

const std::string kHealth = Ref("Health");

const std::string kCrusherList =
    R"j({"type":"object","required":["crushers"],"properties":{"crushers":{"type":"array","items":{"type":"object",
        "required":["crusher_id","installed_at","thickness_new_mm","thickness_min_mm","rows","sensor_count","map_sha256",
        "face_count","latest_reading_time","min_thickness_mm","wear_status","thinnest_area","pending"],
        "properties":{"crusher_id":{"type":"string"},"installed_at":{"type":"string","format":"date-time"},
        "thickness_new_mm":{"type":"number"},"thickness_min_mm":{"type":"number"},
        "rows":{"type":"array","items":{"$ref":"#/components/schemas/Row"}},"sensor_count":{"type":"integer"},
        "map_sha256":{"type":"string"},"face_count":{"type":"integer"},
        "latest_reading_time":{"type":"string","format":"date-time","nullable":true},
        "min_thickness_mm":{"type":"number","nullable":true},
        "wear_status":{"type":"string","nullable":true,"enum":["ok","unsupported","no_sensors"]},
        "thinnest_area":{"nullable":true,"allOf":[{"$ref":"#/components/schemas/ThinnestArea"}]},
        "pending":{"type":"boolean","description":"the server is starting and has not computed this crusher yet"}}}}}})j";

const std::string kCrusherDetail =
    R"j({"type":"object","required":["crusher_id","installed_at","liner_start","concave","sensors","map","counters"],
        "properties":{"crusher_id":{"type":"string"},"installed_at":{"type":"string","format":"date-time"},
        "liner_start":{"type":"string","format":"date-time"},
        "concave":{"type":"object","required":["thickness_new_mm","thickness_min_mm","rows"],"properties":{
          "thickness_new_mm":{"type":"number"},"thickness_min_mm":{"type":"number"},
          "rows":{"type":"array","items":{"$ref":"#/components/schemas/Row"}}}},
        "sensors":{"type":"array","items":{"type":"object","required":["id","row","z_m","theta_deg","thickness_new_mm"],
          "properties":{"id":{"type":"string"},"row":{"type":"string"},"z_m":{"type":"number"},"theta_deg":{"type":"number"},
          "thickness_new_mm":{"type":"number"}}}},
        "map":{"type":"object","required":["sha256","face_count","warnings","has_stderr","windows","dem_summary"],
          "properties":{"sha256":{"type":"string"},"face_count":{"type":"integer"},
          "warnings":{"type":"array","items":{"type":"string"}},"has_stderr":{"type":"boolean"},
          "windows":{"type":"integer"},
          "dem_summary":{"type":"object","nullable":true,"additionalProperties":true,
            "description":"dem_summary.json of a map made by linerwatch dem (docs/dem.md)"}}},
        "counters":{"type":"object","required":["readings_stored","duplicates","conflicts","rejected"],"properties":{
          "readings_stored":{"type":"integer"},"duplicates":{"type":"integer"},"conflicts":{"type":"integer"},
          "rejected":{"type":"integer"}}}}})j";

const std::string kSensorList =
    R"j({"type":"object","required":["sensors"],"properties":{"sensors":{"type":"array","items":{"type":"object",
        "required":["id","row","z_m","theta_deg","thickness_new_mm","reading_count","latest"],
        "properties":{"id":{"type":"string"},"row":{"type":"string"},"z_m":{"type":"number"},"theta_deg":{"type":"number"},
        "thickness_new_mm":{"type":"number"},"reading_count":{"type":"integer","minimum":0},
        "latest":{"nullable":true,"allOf":[{"$ref":"#/components/schemas/StoredReading"}]}}}}}})j";

const std::string kReadingsPage =
    R"j({"type":"object","required":["readings","next_cursor"],"properties":{
        "readings":{"type":"array","items":{"$ref":"#/components/schemas/StoredReading"}},
        "next_cursor":{"type":"string","nullable":true,"description":"null on the last page"}}})j";

const std::string kPostReadingsRequest =
    R"j({"type":"object","required":["readings"],"properties":{"readings":{"type":"array","maxItems":10000,
        "description":"reading messages (docs/mqtt.md); each is checked on its own: a bad one is rejected, the rest stored",
        "items":{"type":"object","required":["sensor","seq","time","thickness_mm","loops_intact","flags","battery_mv"],
        "properties":{"sensor":{"type":"string"},"seq":{"type":"integer","minimum":0,"maximum":4294967295},
        "time":{"type":"string","format":"date-time"},"thickness_mm":{"type":"number"},
        "loops_intact":{"type":"integer","minimum":0,"maximum":4096},"flags":{"type":"integer","minimum":0,"maximum":65535},
        "battery_mv":{"type":"integer","minimum":0,"maximum":10000},"temperature_c":{"type":"number"},
        "ladder_loops":{"type":"integer"},"loop_bitmap":{"type":"string"},"dropped_total":{"type":"integer"},
        "address":{"type":"string"},"gateway":{"type":"string"},"received":{"type":"string"}}}}}})j";

const std::string kPostReadingsResult = Ref("IngestResult");

const std::string kPostReadingsNoneTaken =
    R"j({"allOf":[{"$ref":"#/components/schemas/IngestResult"},{"type":"object","required":["error"],
        "properties":{"error":{"type":"string"}}}]})j";

const std::string kMesh =
    R"j({"type":"object","required":["points","faces","face_z_m","face_theta_deg"],"properties":{
        "points":{"type":"array","items":{"type":"number"},"description":"x y z of each point, flat (metres)"},
        "faces":{"type":"array","items":{"type":"integer","minimum":0},"description":"3 point indices per face, flat"},
        "face_z_m":{"type":"array","items":{"type":"number"}},"face_theta_deg":{"type":"array","items":{"type":"number"}}}})j";

const std::string kWear =
    R"j({"type":"object","required":["crusher_id","time","map_sha256","thickness_new_mm","thickness_min_mm","status",
        "min_thickness_mm","min_thickness_band_mm","thinnest_area","worn_through","setting","map_error_at_sensors","face_level",
        "min","rows","map_model","scan","readings_used","sensors_stale","sensors_stuck","note"],
        "properties":{"crusher_id":{"type":"string"},
        "at":{"type":"string","format":"date-time","description":"only with ?at="},
        "time":{"type":"string","format":"date-time"},"map_sha256":{"type":"string"},
        "thickness_new_mm":{"type":"number"},"thickness_min_mm":{"type":"number"},
        "status":{"type":"string","enum":["ok","unsupported","no_sensors"]},"status_detail":{"type":"string"},
        "min_thickness_mm":{"type":"number","nullable":true},
        "min_thickness_band_mm":{"type":"array","nullable":true,"minItems":2,"maxItems":2,
          "items":{"type":"number","nullable":true}},
        "thinnest_area":{"$ref":"#/components/schemas/ThinnestArea"},"worn_through":{"type":"boolean"},
        "setting":{"type":"object","description":"the closed-side setting's opening by the concave's wear at the discharge ring (docs/wear.md, Setting)",
          "required":["opening_mm","opening_band_mm","css_set_mm","css_mm","css_band_mm","supported","half_width_mm","ring","basis","detail"],
          "properties":{"opening_mm":{"type":"number","nullable":true},
          "opening_band_mm":{"type":"array","minItems":2,"maxItems":2,"items":{"type":"number","nullable":true}},
          "css_set_mm":{"type":"number","nullable":true},"css_mm":{"type":"number","nullable":true},
          "css_band_mm":{"type":"array","nullable":true,"minItems":2,"maxItems":2,"items":{"type":"number","nullable":true}},
          "supported":{"type":"boolean"},"half_width_mm":{"type":"number","nullable":true},
          "ring":{"type":"object","required":["row","z_m","height_m","thickness_mm","nearest_sensor_m","extrapolated"],
            "properties":{"row":{"type":"string"},"z_m":{"type":"number","nullable":true},"height_m":{"type":"number","nullable":true},
            "thickness_mm":{"type":"number","nullable":true},"nearest_sensor_m":{"type":"number","nullable":true},
            "extrapolated":{"type":"boolean"}}},
          "basis":{"type":"string"},"detail":{"type":"string"},
          "opening_since_mm":{"type":"number","nullable":true,"description":"the opening since the CSS was last measured (else since installation)"},
          "checked":{"type":"object","nullable":true,"description":"the measured setting the CSS is counted from (POST .../setting/checks)",
            "required":["time","css_mm","opening_mm","opening_supported","by"],"properties":{"time":{"type":"string","format":"date-time"},
            "css_mm":{"type":"number"},"opening_mm":{"type":"number","nullable":true},"opening_supported":{"type":"boolean"},
            "by":{"type":"string"}}}}},
        "map_error_at_sensors":{"type":"object","required":["factor","sensors","point_rel_sd"],"properties":{
          "factor":{"type":"number","nullable":true},"sensors":{"type":"integer"},
          "point_rel_sd":{"type":"number","nullable":true}}},
        "face_level":{"type":"object","required":["estimate_at_zero_faces","band_reaches_zero_faces"],"properties":{
          "estimate_at_zero_faces":{"type":"integer"},"band_reaches_zero_faces":{"type":"integer"}}},
        "min":{"type":"object","nullable":true,"required":["face","z_m","theta_deg","row"],"properties":{
          "face":{"type":"integer"},"z_m":{"type":"number"},"theta_deg":{"type":"number"},"row":{"type":"string"}}},
        "rows":{"type":"array","items":{"type":"object","required":["row","scale_mm_per_unit","scale_sd","min_thickness_mm",
          "min_thickness_band_mm","min_z_m","min_theta_deg","mean_wear_mm","thinnest_area","worn_through","face_level",
          "sensors_used"],"properties":{"row":{"type":"string"},
          "scale_mm_per_unit":{"type":"number","nullable":true},"scale_sd":{"type":"number","nullable":true},
          "min_thickness_mm":{"type":"number","nullable":true},
          "min_thickness_band_mm":{"type":"array","nullable":true,"minItems":2,"maxItems":2,
            "items":{"type":"number","nullable":true}},
          "min_z_m":{"type":"number","nullable":true},"min_theta_deg":{"type":"number","nullable":true},
          "mean_wear_mm":{"type":"number","nullable":true},"thinnest_area":{"$ref":"#/components/schemas/ThinnestArea"},
          "worn_through":{"type":"boolean"},"face_level":{"type":"object","required":["estimate_at_zero_faces"],
            "properties":{"estimate_at_zero_faces":{"type":"integer"}}},"sensors_used":{"type":"integer"}}}},
        "map_model":{"type":"object","required":["bandwidth_m","bandwidth_arc_m","local_linear","bandwidth_method",
          "noise_source","face_relative_noise","smoothing_error_relative","outlier_faces_capped","windows"],"properties":{
          "bandwidth_m":{"type":"number","nullable":true},"bandwidth_arc_m":{"type":"number","nullable":true},
          "local_linear":{"type":"boolean"},"bandwidth_method":{"type":"string"},"noise_source":{"type":"string"},
          "face_relative_noise":{"type":"number","nullable":true},"smoothing_error_relative":{"type":"number","nullable":true},
          "outlier_faces_capped":{"type":"integer"},"windows":{"type":"integer"}}},
        "scan":{"$ref":"#/components/schemas/Scan"},
        "readings_used":{"type":"array","items":{"$ref":"#/components/schemas/ReadingUsed"}},
        "sensors_stale":{"type":"array","items":{"type":"string"}},"sensors_stuck":{"type":"array","items":{"type":"string"}},
        "note":{"type":"string"},
        "remaining_mm":{"type":"array","nullable":true,"items":{"type":"number"},
          "description":"per face; left out with faces=false, null when no sensor supports the wear"},
        "remaining_sd_mm":{"type":"array","items":{"type":"number"},"description":"per face; left out with faces=false"}}})j";

const std::string kForecast =
    R"j({"type":"object","required":["crusher_id","time","thickness_min_mm","map_sha256","readings_used","rows","sensors",
        "note"],"properties":{"crusher_id":{"type":"string"},
        "at":{"type":"string","format":"date-time","description":"only with ?at="},
        "time":{"type":"string","format":"date-time"},"thickness_min_mm":{"type":"number"},"map_sha256":{"type":"string"},
        "readings_used":{"type":"array","items":{"$ref":"#/components/schemas/ReadingUsed"}},
        "rows":{"type":"array","items":{"type":"object","required":["row","min_thickness_mm","min_thickness_band_mm",
          "rate_mm_per_day","rate_sd_mm_per_day","reach_date","reach_earliest","reach_latest","below_minimum_since",
          "reach_held","reach_set_by_sensor"],"properties":{"row":{"type":"string"},
          "min_thickness_mm":{"type":"number","nullable":true},
          "min_thickness_band_mm":{"type":"array","minItems":2,"maxItems":2,"items":{"type":"number","nullable":true}},
          "rate_mm_per_day":{"type":"number","nullable":true},"rate_sd_mm_per_day":{"type":"number","nullable":true},
          "reach_date":{"type":"string","format":"date-time","nullable":true},
          "reach_earliest":{"type":"string","format":"date-time","nullable":true},
          "reach_latest":{"type":"string","format":"date-time","nullable":true},
          "below_minimum_since":{"type":"string","format":"date-time","nullable":true},
          "reach_held":{"type":"boolean","description":"the date published before is kept: the new one is within its band"},
          "reach_set_by_sensor":{"type":"string","nullable":true},
          "reach_estimate":{"type":"string","format":"date-time","nullable":true,"description":"only when reach_held"},
          "reach_note":{"type":"string"},"note":{"type":"string"}}}},
        "sensors":{"type":"array","items":{"type":"object","required":["id","ok"],"properties":{"id":{"type":"string"},
          "ok":{"type":"boolean","description":"false: no fit (note says why), and none of the fields below"},
          "last_time":{"type":"string","format":"date-time"},"last_reading_mm":{"type":"number"},
          "thickness_interval_mm":{"type":"array","minItems":2,"maxItems":2,"items":{"type":"number"}},
          "thickness_mm":{"type":"number","nullable":true},"rate_mm_per_day":{"type":"number","nullable":true},
          "reach_date":{"type":"string","format":"date-time","nullable":true},
          "reach_earliest":{"type":"string","format":"date-time","nullable":true},
          "reach_latest":{"type":"string","format":"date-time","nullable":true},
          "curve":{"type":"array","items":{"type":"object","required":["time","thickness_mm","lo_mm","hi_mm"],"properties":{
            "time":{"type":"string","format":"date-time"},"thickness_mm":{"type":"number","nullable":true},
            "lo_mm":{"type":"number","nullable":true},"hi_mm":{"type":"number","nullable":true}}}},
          "note":{"type":"string"}}}},
        "note":{"type":"string"}}})j";

// DiagnosisRunner::StatusJson; the result is diagnosis::ToJson (docs/diagnosis.md, Output).
const std::string kDiagnosis =
    R"j({"type":"object","required":["status","time","result"],"properties":{
        "status":{"type":"string","enum":["none","running","done","failed"]},
        "time":{"type":"string","format":"date-time","nullable":true,"description":"of the latest stored diagnosis"},
        "error":{"type":"string","description":"only when failed"},
        "result":{"type":"object","nullable":true,"required":["crusher_id","baseline","mismatch","findings","improved",
          "data_quality","noise","sensors","excluded_sensors","verdict"],"properties":{"crusher_id":{"type":"string"},
          "baseline":{"type":"object","required":["rmse_mm","max_abs_mm","holdout_rmse_mm","observations",
            "holdout_observations"],"properties":{"rmse_mm":{"type":"number"},"max_abs_mm":{"type":"number"},
            "holdout_rmse_mm":{"type":"number"},"observations":{"type":"integer"},"holdout_observations":{"type":"integer"}}},
          "mismatch":{"type":"object","required":["detected","z_score","regions"],"properties":{
            "detected":{"type":"boolean"},"z_score":{"type":"number"},"regions":{"type":"array","items":{"type":"object",
            "required":["z_min_m","z_max_m","theta_min_deg","theta_max_deg","from","to","sign","size_mm","source"],
            "properties":{"z_min_m":{"type":"number"},"z_max_m":{"type":"number"},"theta_min_deg":{"type":"number"},
            "theta_max_deg":{"type":"number"},"from":{"type":"string","format":"date-time"},
            "to":{"type":"string","format":"date-time"},"size_mm":{"type":"number"},"source":{"type":"string"}}}}}},
          "findings":{"type":"array","items":{"type":"object","required":["effect","confidence","explanation"],
            "properties":{"effect":{"type":"string"},"confidence":{"type":"number"},"explanation":{"type":"string"}}}},
          "improved":{"type":"object","required":["rmse_mm","model","what"],"properties":{"rmse_mm":{"type":"number"},
            "model":{"type":"string"},"what":{"type":"string"}}},
          "data_quality":{"type":"array","items":{"type":"object","required":["sensor_id","issue","from","to","detail"],
            "properties":{"sensor_id":{"type":"string"},"issue":{"type":"string"},"from":{"type":"string","format":"date-time"},
            "to":{"type":"string","format":"date-time"},"detail":{"type":"string"}}}},
          "prediction":{"type":"object","required":["time","baseline","improved"],"properties":{
            "time":{"type":"string","format":"date-time"},"baseline":{"$ref":"#/components/schemas/SensorValues"},
            "improved":{"$ref":"#/components/schemas/SensorValues"}},"additionalProperties":true},
          "noise":{"type":"object","required":["model_fits","mismatch_test_blind"],"properties":{
            "model_fits":{"type":"boolean"},"mismatch_test_blind":{"type":"boolean"}}},
          "sensors":{"type":"array","items":{"type":"object","required":["sensor_id","used"],"properties":{
            "sensor_id":{"type":"string"},"used":{"type":"boolean"}}}},
          "excluded_sensors":{"type":"array","items":{"type":"object","required":["sensor_id","reason"],"properties":{
            "sensor_id":{"type":"string"},"reason":{"type":"string"}}}},
          "verdict":{"type":"object","required":["kind","headline","detail"],"properties":{
            "kind":{"type":"string","enum":["mismatch_explained","mismatch_unexplained","no_mismatch","not_testable",
            "noise_model_does_not_fit"]},"headline":{"type":"string"},"detail":{"type":"string"}}}}}}})j";

const std::string kDiagnosisStarted =
    R"j({"type":"object","required":["status"],"properties":{"status":{"type":"string","enum":["running"]}}})j";

const std::string kAlarmRules = AlarmRulesSchema(true);
const std::string kAlarmRulesRequest = AlarmRulesSchema(false);

const std::string kRejectedList =
    R"j({"type":"object","required":["total","evicted","rejected"],"properties":{"total":{"type":"integer","minimum":0},
        "evicted":{"type":"integer","minimum":0,"description":"the oldest dropped beyond the quarantine's cap"},
        "rejected":{"type":"array","items":{"type":"object","required":["received","topic","payload","reason","class"],
          "properties":{"received":{"type":"string","format":"date-time"},"topic":{"type":"string"},
          "payload":{"type":"string"},"reason":{"type":"string"},"class":{"type":"string"}}}}}})j";

const std::string kWhoAmI =
    R"j({"type":"object","required":["auth","name","scopes"],"properties":{
        "auth":{"type":"boolean","description":"false: the server runs without --tokens"},
        "name":{"type":"string","nullable":true,"description":"the token's name; null without --tokens"},
        "scopes":{"type":"array","items":{"type":"string","enum":["read","write"]}}}})j";

const std::string kOpenApi =
    R"j({"type":"object","required":["openapi","info","paths","components"],"properties":{
        "openapi":{"type":"string","enum":["3.0.3"]},"info":{"type":"object","required":["title","version"],"properties":{
          "title":{"type":"string"},"version":{"type":"string"},"description":{"type":"string"}}},
        "paths":{"type":"object","additionalProperties":{"type":"object","additionalProperties":{"type":"object",
          "required":["responses"],"properties":{"responses":{"type":"object","additionalProperties":true}}}}},
        "components":{"type":"object","properties":{"schemas":{"type":"object","additionalProperties":true}}}}})j";

const std::string kEventStream =
    R"j({"type":"string","description":"Server-Sent Events: first `retry: 3000` and a `: connected` comment, then `id: N`, `event: reading|wear|alarm`, `data: JSON` records, and a `: keepalive` comment every 15 s without events. Resume with the Last-Event-ID header."})j";

}  // namespace lw::server::rest::schemas
