#include "cli/cli.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "core/atomic_file.hpp"
#include "core/bundle.hpp"
#include "core/cmdline.hpp"
#include "core/reconstruction.hpp"
#include "core/thinnest_area.hpp"
#include "core/time.hpp"
#include "core/wear_map.hpp"
#include "dem/case_writer.hpp"
#include "dem/chamber.hpp"
#include "dem/map_builder.hpp"
#include "dem/runner.hpp"
#include "dem/until.hpp"
#include "diagnosis/diagnose.hpp"
#include "estimate/estimate.hpp"
#include "estimate/plan.hpp"
#include "remote.hpp"

namespace lw::cli {
namespace {

namespace fs = std::filesystem;

using core::Option;

// One option table per command: parsing, checks and the option lines of --help come from it.
const core::OptionTable& DiagnoseTable() {
  static const core::OptionTable table(
      {
          Option::Text("json", "OUT.json", "the diagnosis as JSON (docs/diagnosis.md)").Required(),
          Option::Text("html", "OUT.html", "the same as a self-contained HTML report"),
          Option::Text("predict-at", "TIME", "predict the wear map at TIME, with and without the findings"),
          Option::Text("predict-vtk", "OUT.vtk", "that prediction as a VTK map (needs --predict-at)"),
          Option::Switch("no-pairs", "single effects only (faster)"),
      },
      "BUNDLE", "bundle");
  return table;
}

const core::OptionTable& ReconstructTable() {
  static const core::OptionTable table(
      {
          Option::Text("at", "TIME", "the sensors' latest readings at TIME (default: the last reading)"),
          Option::Text("json", "OUT.json", "per-row summary and wear map statistics as JSON"),
          Option::Text("vtk", "OUT.vtk", "the global wear map as VTK"),
          Option::Switch("lower-bound", "reading n is n mm (the thinnest), not n + 0.5"),
          Option::Switch("no-scan", "the map alone, without the latest scan's correction"),
      },
      "BUNDLE", "bundle");
  return table;
}

const core::OptionTable& DemTable() {
  static const core::OptionTable table(
      {
          Option::Text("work", "DIR", "case folder (default CRUSHER_DIR/dem)"),
          Option::Text("stage", "case|run|map|all", "what to do (default all)"),
          Option::Whole("np", "N", 1, 4096, "MPI processes (default 2)"),
          Option::Whole("windows", "K", 2, 100, "independent time windows for wear_stderr (default: as many as fit, at most 8)"),
          Option::Switch("install", "copy the map into CRUSHER_DIR"),
          Option::Text("mpirun", "PATH", "mpirun to use"),
          Option::Text("liggghts", "PATH", "LIGGGHTS executable to use"),
          Option::Whole("progress-every", "S", 1, 3600, "seconds between progress lines (default 10)"),
          Option::Number("until-band", "MM", core::NumberRange::Positive(),
                         "resume the run for more simulated time until the map's band at the patch is at most +/-MM mm"),
          Option::Number("patch", "M", core::NumberRange::Positive(),
                         "the square patch's side for --until-band, m (default the thinnest-area ladder's first)"),
          Option::Number("max-hours", "H", core::NumberRange::Positive(), "wall-time budget of --until-band (default none)"),
      },
      "CRUSHER_DIR", "bundle");
  return table;
}

const core::OptionTable& PlanTable() {
  static const core::OptionTable table(
      {
          Option::Whole("sensors", "K", 1, 10000, "how many sensors the next liner gets").Required(),
          Option::Text("json", "OUT.json", "the plan as JSON (docs/plan.md)"),
          Option::Number("edge-margin-m", "M", core::NumberRange{0, 10},
                         "keep sensors M m inside each row's edges (default 0.1)"),
          Option::Number("joint-clearance-deg", "D", core::NumberRange{0, 90},
                         "keep sensors D degrees from concave.joints_theta_deg (default 5)"),
      },
      "CRUSHER_DIR", "bundle");
  return table;
}

std::string Usage() {
  return "usage: linerwatch <command> [options]\n"
         "\n"
         "commands:\n"
         "  diagnose BUNDLE " +
         DiagnoseTable().Synopsis(18, 100) +
         "\n"
         "      Compare the bundle's readings (and scans) with the Eq. 9 reconstruction of its DEM map, test\n"
         "      whether the mismatch is real, locate it, and name the physics the DEM left out.\n"
         "      Exit 0 when the diagnosis ran, whatever it found (docs/diagnosis.md, section Output).\n" +
         DiagnoseTable().Help(28, 6, false) + "  reconstruct BUNDLE " + ReconstructTable().Synopsis(21, 100) +
         "\n"
         "      Eq. 9 global wear from the sensors' latest readings (at TIME, default: the last reading);\n"
         "      prints a per-row summary. A reading n means [n, n+1) mm: estimates use n + 0.5, as the\n"
         "      server does; --lower-bound uses n (the thinnest the liner can be). The latest scan at or\n"
         "      before TIME corrects the map between the sensors (--no-scan: the map alone).\n" +
         ReconstructTable().Help(28, 6, false) + "  dem CRUSHER_DIR " + DemTable().Synopsis(18, 100) +
         "\n"
         "      Make the crusher's DEM wear map with LIGGGHTS from the \"chamber\" of its crusher.json\n"
         "      (defaults: a 62-75 primary gyratory; docs/dem.md): write the case (STL meshes, input\n"
         "      script, Slurm script, MPI hostfile example) into DIR (default CRUSHER_DIR/dem), run it with\n"
         "      `mpirun -np N liggghts` (default N 2; after a stop it resumes from the newest restart\n"
         "      file), and build DIR/wear_map.vtk (wear over the steady, choke-fed span; wear_stderr from\n"
         "      K independent time windows; averaged stresses), wear_windows.vtk and dem_summary.json.\n"
         "      --install then copies them into CRUSHER_DIR (replacing its wear_map.vtk). --until-band MM\n"
         "      then resumes the run for more simulated time, in steps (each printed with its projected\n"
         "      simulated and wall time), until the live wear's band of the thinnest --patch square at the\n"
         "      reline point, from this map, is at most +/-MM mm; --max-hours stops it (exit 1).\n" +
         DemTable().Help(28, 6, false) + "  plan CRUSHER_DIR " + PlanTable().Synopsis(19, 100) +
         "\n"
         "      Where to cast the next liner's K sensors (per row: z_m, theta_deg; inside each row by the margin,\n"
         "      clear of concave.joints_theta_deg) so that the live wear's band at the reline point is narrowest,\n"
         "      judged by the live wear's own band model on the DEM map's errors; compared with the crusher.json\n"
         "      layout. With readings.csv (a running campaign) it also says how much a laser scan now would\n"
         "      narrow the bands and the reline date (docs/plan.md).\n" +
         PlanTable().Help(28, 6, false) + RemoteUsage(28, 6) +
         "\n"
         "options:\n"
         "  --config FILE   JSON object with the same options, e.g. {\"bundle\": \"b\", \"json\": \"out.json\",\n"
         "                  \"predict_at\": \"2024-05-01\"}; command-line flags override it\n"
         "  --help          this text\n"
         "TIME is ISO-8601 UTC (YYYY-MM-DD or YYYY-MM-DDTHH:MM:SSZ).\n";
}

/// A one-line, user-facing error: exit status 2.
using core::UsageError;
/// Bad input (a file, a bundle): exit status 1.
struct BadInput : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// A command's parsed options; the positional argument (or the config file's "bundle") is "bundle".
struct Options {
  core::ParsedOptions parsed;
  bool Has(const std::string& k) const { return k == "bundle" ? !parsed.positional().empty() : parsed.Has(k); }
  std::string Get(const std::string& k) const { return k == "bundle" ? parsed.positional() : parsed.Text(k); }
  bool Flag(const std::string& k) const { return parsed.Switch(k); }
};

/// args[0] is the command.
Options Parse(const core::OptionTable& table, const std::vector<std::string>& args) {
  return {core::ParseOptions(table, std::vector<std::string>(args.begin() + 1, args.end()))};
}

core::TimePoint ParseTime(const std::string& text, const std::string& option) {
  auto t = core::ParseIsoTime(text);
  if (!t) throw UsageError("--" + option + ": '" + text + "' is not an ISO-8601 time (YYYY-MM-DD[THH:MM:SSZ])");
  return *t;
}

void CheckWritable(const std::string& path, const std::string& option) {
  const fs::path p(path);
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw BadInput("--" + option + ": directory " + dir.string() + " does not exist");
  if (fs::is_directory(p, ec)) throw BadInput("--" + option + ": " + path + " is a directory");
}

/// Output files written to temporaries, all renamed only when every one was written.
class OutputSet {
 public:
  ~OutputSet() {
    std::error_code ec;
    for (const auto& f : pending_) fs::remove(f.second, ec);
  }
  void Add(const std::string& path, const std::string& content) {
    fs::path tmp = path;
    tmp += ".tmp" + std::to_string(pending_.size());
    std::ofstream out(tmp, std::ios::binary);
    if (!out) throw BadInput(path + ": cannot write");
    out << content;
    out.close();
    if (!out) throw BadInput(path + ": write failed");
    pending_.push_back({path, tmp});
  }
  void Commit() {
    for (const auto& f : pending_) fs::rename(f.second, f.first);
    pending_.clear();
  }

 private:
  std::vector<std::pair<std::string, fs::path>> pending_;
};

core::Bundle Load(const Options& o) {
  if (!o.Has("bundle")) throw UsageError("missing BUNDLE (a campaign folder)");
  const fs::path dir = o.Get("bundle");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw BadInput(dir.string() + ": not a directory (a bundle is a folder)");
  return core::LoadBundle(dir);
}

int Diagnose(const std::vector<std::string>& args, std::ostream& out) {
  const Options o = Parse(DiagnoseTable(), args);
  CheckWritable(o.Get("json"), "json");
  if (o.Has("html")) CheckWritable(o.Get("html"), "html");
  if (o.Has("predict_vtk")) {
    CheckWritable(o.Get("predict_vtk"), "predict-vtk");
    if (!o.Has("predict_at")) throw UsageError("--predict-vtk needs --predict-at TIME");
  }
  diagnosis::DiagnoseOptions opt;
  if (o.Has("predict_at")) opt.predict_at = ParseTime(o.Get("predict_at"), "predict-at");
  opt.try_pairs = !o.Flag("no_pairs");
  const core::Bundle bundle = Load(o);
  const diagnosis::DiagnosisResult result = diagnosis::Diagnose(bundle, opt);

  OutputSet outputs;
  outputs.Add(o.Get("json"), diagnosis::ToJson(result).dump(2) + "\n");
  if (o.Has("html")) outputs.Add(o.Get("html"), diagnosis::RenderHtml(result));
  if (o.Has("predict_vtk")) diagnosis::WritePredictionVtk(o.Get("predict_vtk"), bundle, result);
  try {
    outputs.Commit();
  } catch (...) {
    std::error_code ec;
    if (o.Has("predict_vtk")) fs::remove(o.Get("predict_vtk"), ec);
    throw;
  }
  out << "diagnosis of " << result.crusher_id << ": " << diagnosis::DescribeVerdict(result).headline << "; "
      << result.findings.size() << " finding(s)";
  if (!result.findings.empty()) out << ", top: " << result.findings.front().effect;
  out << "; " << result.data_quality.size() << " data-quality issue(s)\n";
  return 0;
}

std::string Percent(double rel) {
  char b[32];
  std::snprintf(b, sizeof b, "%.0f %%", 100.0 * rel);
  return b;
}

/// The per-row summary `linerwatch reconstruct` prints: the map model, the scan applied, the sensors
/// left out, each row, the thinnest face and the thinnest areas the data support.
void PrintReconstruction(const estimate::CrusherModel& model, const estimate::WearEstimate& est, std::ostream& out) {
  const core::Reconstruction& rec = est.reconstruction;
  const core::MapModel& m = model.plan.model;
  char line[320];
  std::snprintf(line, sizeof line,
                "map model: smoothing %.3f m along z, %.3f m around (%s), per-face noise %.0f %% (%s), smoothing error %.1f %%, "
                "%zu outlier faces capped\n",
                m.bandwidth_m, m.bandwidth_arc_m, m.bandwidth_method.c_str(), 100.0 * m.face_cv, m.noise_source.c_str(),
                100.0 * m.smoothing_error_rel, m.outlier_faces);
  out << line;
  if (est.scan) {
    const estimate::ModelScan& s = model.ScanOf(*est.scan);
    const core::ScanCorrection& c = est.scan->correction;
    if (const auto& p = est.scan->prior) {
      // The previous liner's pattern stands in for a scan of this one: say how far it is trusted and why.
      std::snprintf(line, sizeof line,
                    "no scan of this liner: the prior is campaign %s's end-of-life scan; pattern change between campaigns "
                    "taken as %.0f %% per face (%s)\n",
                    model.prior->campaign.c_str(), 100.0 * p->change_rel,
                    p->dof > 0
                        ? ("this liner's sensors spread " + Percent(p->spread_prior_rel) + " around its pattern, " +
                           Percent(p->spread_map_rel) + " around the DEM map's, " + std::to_string(p->sensors) +
                           " sensors worn " + std::to_string(static_cast<int>(estimate::PriorCheck::kMinWearMm)) + " mm or more")
                              .c_str()
                        : "assumed: fewer than two sensors of a row have worn enough to compare");
      out << line;
    }
    if (c.detail.empty())
      std::snprintf(line, sizeof line,
                    "scan %s (%s): %zu of %zu points on the map, %zu faces corrected (%zu more from their neighbours), "
                    "median corrected/map intensity %.2f\n",
                    s.scan.file.c_str(), core::FormatIsoTime(s.scan.date).c_str(), s.faces.points_used, s.faces.points_total,
                    c.faces_corrected, c.faces_filled, c.median_ratio);
    else
      std::snprintf(line, sizeof line, "scan %s not applied: %s\n", s.scan.file.c_str(), c.detail.c_str());
    out << line;
  }
  if (!est.stale.empty()) {
    out << "stale sensors (latest reading more than 8 reporting periods behind the newest; no row scale):";
    for (const std::string& id : est.stale) out << ' ' << id;
    out << '\n';
  }
  if (!est.stuck.empty()) {
    out << "stuck sensors (one value while the other sensors of their row wore 8 mm or more; no row scale):";
    for (const std::string& id : est.stuck) out << ' ' << id;
    out << '\n';
  }
  out << "row        scale_mm/unit  mean_wear_mm  min_thickness_mm  band_mm (+/-2 sd)  at_z_m  at_theta_deg  sensors\n";
  for (const core::RowSummary& r : rec.rows) {
    std::snprintf(line, sizeof line, "%-10s %13.4f %13.2f %17.2f  %7.2f..%-7.2f  %7.3f %13.1f %8zu\n", r.row.c_str(),
                  r.scale_mm_per_unit, r.mean_wear_mm, r.min_thickness_mm, r.min_thickness_lo_mm, r.min_thickness_hi_mm,
                  r.min_z_m, r.min_theta_deg, r.sensors_used);
    out << line;
  }
  if (rec.status == core::kStatusNoSensors) {
    out << "minimum remaining thickness: not supported (" << rec.status_detail << ")\n";
  } else {
    std::snprintf(line, sizeof line, "minimum remaining thickness %.2f mm (band %.2f..%.2f mm, face %zu)%s%s\n",
                  rec.min_thickness_mm, rec.min_thickness_lo_mm, rec.min_thickness_hi_mm, rec.min_face,
                  rec.status == core::kStatusOk ? "" : ": ", rec.status == core::kStatusOk ? "" : rec.status_detail.c_str());
    out << line;
  }
  if (rec.calibration.sensors > 0) {
    std::snprintf(line, sizeof line,
                  "map error measured at the sensors: %.2f x the map model's (%zu sensors predicted from their row mates)\n",
                  rec.calibration.factor, rec.calibration.sensors);
    out << line;
  }
  // The headline: the thinnest area the data support (the face minimum above is a single face's).
  out << core::ThinnestAreaText(est.areas.liner) << '\n';
  for (const core::ThinnestArea& a : est.areas.rows) out << "  " << core::ThinnestAreaText(a) << '\n';
  out << core::SettingText(est.setting) << '\n';
}

/// `linerwatch reconstruct --json`: per-row summary and wear map statistics (docs/diagnosis.md).
nlohmann::ordered_json ReconstructionJson(const estimate::CrusherModel& model, const estimate::WearEstimate& est,
                                          const std::optional<core::TimePoint>& at) {
  const core::Reconstruction& rec = est.reconstruction;
  const core::MapModel& m = model.plan.model;
  auto num = [](double v) { return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr); };
  nlohmann::ordered_json j;
  j["crusher_id"] = model.config.crusher_id;
  if (at) j["at"] = core::FormatIsoTime(*at);
  j["status"] = rec.status;
  if (!rec.status_detail.empty()) j["status_detail"] = rec.status_detail;
  j["min_thickness_mm"] = num(rec.min_thickness_mm);
  j["min_thickness_band_mm"] = {num(rec.min_thickness_lo_mm), num(rec.min_thickness_hi_mm)};
  j["min_face"] = rec.min_face;
  j["thinnest_area"] = core::ThinnestAreaJson(est.areas.liner);
  j["worn_through"] = est.areas.liner.worn_through;
  j["setting"] = core::SettingJson(est.setting);
  j["map_error_at_sensors"] = core::MapCalibrationJson(rec.calibration);
  j["face_level"] = {{"estimate_at_zero_faces", rec.worn_through_faces},
                     {"band_reaches_zero_faces", rec.maybe_worn_through_faces}};
  j["sensors_stale"] = est.stale;
  j["sensors_stuck"] = est.stuck;
  j["scan"] = estimate::ScanJson(model, est.scan.get());
  j["map_model"] = {{"bandwidth_m", m.bandwidth_m},
                    {"bandwidth_arc_m", m.bandwidth_arc_m},
                    {"local_linear", m.local_linear},
                    {"bandwidth_method", m.bandwidth_method},
                    {"noise_source", m.noise_source},
                    {"face_relative_noise", m.face_cv},
                    {"smoothing_error_relative", m.smoothing_error_rel},
                    {"outlier_faces_capped", m.outlier_faces}};
  j["rows"] = nlohmann::ordered_json::array();
  for (size_t k = 0; k < rec.rows.size(); ++k) {
    const core::RowSummary& r = rec.rows[k];
    nlohmann::ordered_json x;
    x["row"] = r.row;
    x["scale_mm_per_unit"] = num(r.scale_mm_per_unit);
    x["scale_sd"] = num(r.scale_sd);
    x["mean_wear_mm"] = num(r.mean_wear_mm);
    x["min_thickness_mm"] = num(r.min_thickness_mm);
    x["min_thickness_band_mm"] = {num(r.min_thickness_lo_mm), num(r.min_thickness_hi_mm)};
    x["min_z_m"] = r.min_z_m;
    x["min_theta_deg"] = r.min_theta_deg;
    x["thinnest_area"] = core::ThinnestAreaJson(est.areas.rows[k]);
    x["worn_through"] = est.areas.rows[k].worn_through;
    x["face_level"] = {{"estimate_at_zero_faces", r.worn_through_faces}};
    x["sensors_used"] = r.sensors_used;
    j["rows"].push_back(x);
  }
  j["sensors"] = nlohmann::ordered_json::object();
  for (const auto& w : est.sensor_wear) j["sensors"][w.sensor_id] = w.wear_mm;
  return j;
}

int Reconstruct(const std::vector<std::string>& args, std::ostream& out) {
  const Options o = Parse(ReconstructTable(), args);
  if (o.Has("json")) CheckWritable(o.Get("json"), "json");
  if (o.Has("vtk")) CheckWritable(o.Get("vtk"), "vtk");
  std::optional<core::TimePoint> at;
  if (o.Has("at")) at = ParseTime(o.Get("at"), "at");
  const core::Bundle bundle = Load(o);
  // Live wear as the server computes it (estimate::Estimate): each sensor's latest reading at or
  // before `at`, a reading n meaning [n, n+1) mm so n + 0.5 (docs/bundle.md; --lower-bound: n itself,
  // thinner); stale and stuck sensors set no scale; the latest scan at or before `at` corrects the
  // map between the sensors (--no-scan: the map alone).
  const std::unique_ptr<estimate::CrusherModel> model = estimate::CrusherModel::FromBundle(bundle);
  estimate::EstimateOptions options;
  options.interval_centre = !o.Flag("lower_bound");
  options.use_scans = !o.Flag("no_scan");
  options.forecast = false;  // reconstruct prints wear, not reline dates
  const estimate::WearEstimate est = estimate::Estimate(*model, estimate::SamplesOf(bundle.readings), at, options);
  if (est.sensor_wear.empty()) {
    const auto previous = std::count_if(bundle.readings.begin(), bundle.readings.end(), [&](const core::Reading& r) {
      return !bundle.crusher.OfThisLiner(r.sensor_id, r.time, r.thickness_mm);
    });
    throw BadInput(bundle.dir.string() + "/readings.csv: no reading of this liner at or before the requested time" +
                   (previous > 0 ? " (" + std::to_string(previous) +
                                       " of its readings are a previous liner's: dated before installed_at " +
                                       core::FormatIsoTime(bundle.crusher.installed_at) + ")"
                                 : std::string()));
  }
  PrintReconstruction(*model, est, out);
  OutputSet outputs;
  if (o.Has("json")) outputs.Add(o.Get("json"), ReconstructionJson(*model, est, at).dump(2) + "\n");
  const core::Reconstruction& rec = est.reconstruction;
  if (o.Has("vtk")) {
    core::WriteWearMapVtk(
        o.Get("vtk"), model->map,
        {{"wear_mm", &rec.wear_mm}, {"remaining_mm", &rec.remaining_mm}, {"remaining_sd_mm", &rec.remaining_sd_mm}});
  }
  try {
    outputs.Commit();
  } catch (...) {
    std::error_code ec;
    if (o.Has("vtk")) fs::remove(o.Get("vtk"), ec);
    throw;
  }
  return 0;
}

/// A crusher folder (crusher.json, its map, scans/) with readings.csv when it has one: the plan's
/// input. A folder with readings is a running campaign.
core::Bundle LoadCrusherDir(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw BadInput(dir.string() + ": not a directory (a crusher folder holds crusher.json)");
  if (!fs::is_regular_file(dir / "crusher.json", ec))
    throw BadInput((dir / "crusher.json").string() + ": missing (a crusher folder holds crusher.json)");
  if (fs::exists(dir / "readings.csv", ec)) return core::LoadBundle(dir);
  core::Bundle b;
  b.dir = dir;
  b.crusher = core::LoadCrusherConfig(dir / "crusher.json");
  fs::path map = dir / "wear_map.vtk";
  if (!fs::exists(map, ec) && fs::exists(dir / "wear_map.csv", ec)) map = dir / "wear_map.csv";
  if (!fs::exists(map, ec))
    throw BadInput((dir / "wear_map.vtk").string() +
                   ": missing (the plan needs the crusher's DEM wear map; linerwatch dem makes one)");
  b.map = core::LoadWearMap(map, &b.map_validation);
  core::CheckCrusherAgainstMap(b.crusher, b.map, "crusher.json");
  b.scans = core::LoadScans(dir);
  return b;
}

int Plan(const std::vector<std::string>& args, std::ostream& out) {
  const Options o = Parse(PlanTable(), args);
  if (!o.Has("bundle")) throw UsageError("plan needs CRUSHER_DIR (a folder with crusher.json and wear_map.vtk)");
  if (o.Has("json")) CheckWritable(o.Get("json"), "json");
  estimate::PlanOptions options;
  options.sensors = o.parsed.Integer<size_t>("sensors", 0);
  options.edge_margin_m = o.parsed.Number("edge-margin-m", options.edge_margin_m);
  options.joint_clearance_deg = o.parsed.Number("joint-clearance-deg", options.joint_clearance_deg);
  const core::Bundle bundle = LoadCrusherDir(o.Get("bundle"));
  const std::unique_ptr<estimate::CrusherModel> model = estimate::CrusherModel::FromBundle(bundle);
  estimate::SensorPlan plan;
  try {
    plan = estimate::PlanSensors(*model, options);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  if (!bundle.readings.empty()) plan.scan = estimate::AdviseScan(*model, estimate::SamplesOf(bundle.readings));
  if (o.Has("json")) core::WriteFileAtomically(o.Get("json"), estimate::PlanJson(plan).dump(2) + "\n");
  out << estimate::PlanText(plan);
  return 0;
}

extern "C" void OnStopSignal(int) {
  dem::RequestStop();
}

/// Runs the case in `work` (or resumes it) with SIGINT and SIGTERM stopping LIGGGHTS, not this process.
dem::RunResult RunStage(const dem::ChamberSpec& spec, const fs::path& work, const dem::RunOptions& run, std::ostream& out) {
  std::error_code ec;
  if (!fs::is_regular_file(work / dem::CaseLayout::kInput, ec))
    throw BadInput(work.string() + ": no case here (run with --stage case first)");
  struct sigaction sa {};
  sa.sa_handler = OnStopSignal;
  sigemptyset(&sa.sa_mask);
  struct sigaction old_int {
  }, old_term{};
  sigaction(SIGINT, &sa, &old_int);
  sigaction(SIGTERM, &sa, &old_term);
  const dem::RunResult r = dem::RunCase(spec, work, run, out);
  sigaction(SIGINT, &old_int, nullptr);
  sigaction(SIGTERM, &old_term, nullptr);
  if (r.completed)
    out << "dem: run complete"
        << (r.wall_s > 0 ? " after " + std::to_string(std::lround(r.wall_s)) + " s of wall time" : std::string()) << "\n";
  return r;
}

/// Builds the map from the run in `work` and prints its summary.
nlohmann::json MapStage(const dem::ChamberSpec& spec, const fs::path& work, const core::CrusherConfig& crusher, int windows,
                        std::ostream& out) {
  nlohmann::json summary;
  try {
    summary = dem::BuildMap(spec, work, crusher.rows, work, windows);
  } catch (const std::runtime_error& e) {
    throw BadInput(e.what());
  }
  out << "dem: " << (work / dem::MapFiles::kMap).string() << ": " << summary["faces"].get<size_t>() << " faces, "
      << summary["windows"]["count"].get<int>() << " windows of " << summary["windows"]["window_s"].get<double>()
      << " s from t = " << summary["steady"]["from_s"].get<double>() << " s, median relative stderr "
      << summary["median_rel_stderr"].get<double>() << "\n";
  for (const auto& r : summary["rows"]) {
    char line[200];
    std::snprintf(line, sizeof line, "dem:   %-6s mean %.4g  ratio %.2f  CV %.2f  faces >10x mean %d\n",
                  r["row"].get<std::string>().c_str(), r["mean_wear"].get<double>(), r["ratio"].get<double>(),
                  r["cv"].get<double>(), r["faces_over_10x_mean"].get<int>());
    out << line;
  }
  if (!summary["steady"]["note"].get<std::string>().empty())
    out << "dem: caution: " << summary["steady"]["note"].get<std::string>() << "\n";
  if (!summary["steady"]["choke_fed"].get<bool>())
    out << "dem: caution: the hopper ran empty in the steady span (not choke fed)\n";
  return summary;
}

void InstallMap(const fs::path& work, const fs::path& crusher_dir, std::ostream& out) {
  for (const char* f : {dem::MapFiles::kMap, dem::MapFiles::kWindows, dem::MapFiles::kSummary})
    core::CopyFileAtomically(work / f, crusher_dir / f);
  out << "dem: installed wear_map.vtk, wear_windows.vtk and dem_summary.json into " << crusher_dir.string() << "\n";
}

/// --until-band, --patch, --max-hours.
struct UntilOptions {
  double band_mm = 0;
  double patch_m = 0;
  double max_hours = std::numeric_limits<double>::infinity();
};

/// The map's band at the patch (estimate::MapBandAt) for the map just built in `work`, printed.
estimate::MapBand BandOfMap(const core::CrusherConfig& crusher, const fs::path& work, const UntilOptions& u, std::ostream& out) {
  core::Bundle bundle;
  bundle.dir = work;
  bundle.crusher = crusher;
  bundle.map = core::LoadWearMap(work / dem::MapFiles::kMap, &bundle.map_validation);
  const std::unique_ptr<estimate::CrusherModel> model = estimate::CrusherModel::FromBundle(bundle);
  estimate::MapBand b;
  try {
    b = estimate::MapBandAt(*model, u.patch_m);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  char line[400];
  std::snprintf(line, sizeof line,
                "dem: band +/-%.2f mm, target +/-%.2f mm (the live wear's, %.0f sd, of the thinnest %.2f m patch at the "
                "reline point: row %s, z %.2f m, theta %.0f deg; sd %.2f mm from the map there, %.2f mm from the row scale)\n",
                b.half_width_mm, u.band_mm, b.band_sigmas, b.patch_m, b.row.c_str(), b.z_m, b.theta_deg, b.map_sd_mm,
                b.scale_sd_mm);
  out << line;
  return b;
}

/// `dem --until-band`: run, map, and resume for more simulated time until the map's band at the
/// patch is within the target or the wall-time budget is spent (docs/dem.md). Exit 0 when within.
int DemUntil(dem::ChamberSpec spec, const core::CrusherConfig& crusher, const fs::path& crusher_dir, const fs::path& work,
             dem::RunOptions run, int windows, const UntilOptions& u, bool install, std::ostream& out) {
  const auto t0 = std::chrono::steady_clock::now();
  if (std::isfinite(u.max_hours))
    run.deadline =
        t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(u.max_hours * 3600));
  // A case folder that already ran longer than crusher.json asks (an earlier --until-band) goes on from there.
  const auto dumps = dem::StepsInFolder(work / dem::CaseLayout::kDumpDir, "concave_", ".vtk");
  if (!dumps.empty()) spec.simulated_s = std::max(spec.simulated_s, static_cast<double>(dumps.back()) * spec.timestep_s);
  dem::WriteCase(spec, work);
  std::vector<dem::BandAfter> so_far;
  double run_wall = 0, run_simulated = 0;  // this call's LIGGGHTS time and the simulated time it advanced
  double completed_s = 0;                  // the last simulated time the run completed
  for (;;) {
    const dem::RunResult r = RunStage(spec, work, run, out);
    run_wall += r.wall_s;
    if (r.wall_s > 0) run_simulated += spec.simulated_s - static_cast<double>(r.resumed_from_step) * spec.timestep_s;
    if (!r.completed && !r.out_of_time) throw BadInput(r.message);
    dem::ChamberSpec as_run = spec;  // out of time: the map of every dump so far, on the last completed length
    if (r.out_of_time) as_run.simulated_s = completed_s;
    nlohmann::json summary;
    try {
      summary = MapStage(as_run, work, crusher, windows, out);
    } catch (const BadInput& e) {
      if (!r.out_of_time) throw;
      char b[200];
      std::snprintf(b, sizeof b, "--max-hours %g: the budget is spent before the run made a map (", u.max_hours);
      throw BadInput(b + std::string(e.what()) + "); dumps and restart files are kept: run again to resume");
    }
    completed_s = as_run.simulated_s;
    const estimate::MapBand band = BandOfMap(crusher, work, u, out);
    const double to_s = summary["steady"]["to_s"].get<double>();
    so_far.push_back({to_s, to_s - summary["steady"]["from_s"].get<double>(), band.half_width_mm});
    dem::UntilBudget budget;
    budget.wall_per_simulated_s = run_simulated > 0 ? run_wall / run_simulated
                                  : summary["runtime_s"].get<double>() > 0
                                      ? summary["runtime_s"].get<double>() / summary["simulated_s"].get<double>()
                                      : std::numeric_limits<double>::quiet_NaN();
    const auto restarts = dem::StepsInFolder(work / dem::CaseLayout::kRestartDir, "crusher.", ".restart");
    budget.resume_from_s = restarts.empty() ? 0.0 : static_cast<double>(restarts.back()) * spec.timestep_s;
    budget.remaining_wall_s = std::chrono::duration<double>(run.deadline - std::chrono::steady_clock::now()).count();
    if (r.out_of_time) budget.remaining_wall_s = 0;
    budget.dump_interval_s = spec.dump_interval_s;
    budget.min_step_s = std::max(3 * 60.0 / spec.speed_rpm, spec.dump_interval_s);
    const dem::UntilStep step = dem::PlanUntilStep(so_far, u.band_mm, budget);
    char line[500];
    if (step.verdict == dem::UntilStep::Verdict::kDone) {
      std::snprintf(line, sizeof line, "dem: precise enough after %.1f s simulated (%.1f s steady): +/-%.2f mm <= %.2f mm\n",
                    to_s, so_far.back().steady_s, band.half_width_mm, u.band_mm);
      out << line;
      if (install) InstallMap(work, crusher_dir, out);
      return 0;
    }
    std::snprintf(line, sizeof line,
                  "dem: projected: %.1f s simulated in all (%.1f s steady; the band falling as T^-%.2f, %s), about %s of wall "
                  "time from the restart at %.1f s\n",
                  step.projected_simulated_s, step.needed_steady_s, step.exponent,
                  step.measured ? "measured over the steps so far" : "the 1/sqrt(T) law of sampling noise",
                  core::FormatDuration(step.projected_wall_s).c_str(), budget.resume_from_s);
    out << line;
    if (step.verdict == dem::UntilStep::Verdict::kBudget) {
      if (install) InstallMap(work, crusher_dir, out);
      std::snprintf(line, sizeof line,
                    "--max-hours %g: the budget is spent after %.1f s simulated with the band at +/-%.2f mm (target %.2f "
                    "mm); the map of every window so far is in %s; run again with more hours to go on from the newest restart",
                    u.max_hours, to_s, band.half_width_mm, u.band_mm, (work / dem::MapFiles::kMap).string().c_str());
      throw BadInput(line);
    }
    std::snprintf(line, sizeof line, "dem: next step: to %.1f s simulated, about %s of wall time (%s left of the budget)\n",
                  step.next_simulated_s, core::FormatDuration(step.step_wall_s).c_str(),
                  std::isfinite(u.max_hours) ? core::FormatDuration(budget.remaining_wall_s).c_str() : "no limit");
    out << line;
    out.flush();
    spec.simulated_s = step.next_simulated_s;
    dem::WriteCase(spec, work);
  }
}

int Dem(const std::vector<std::string>& args, std::ostream& out) {
  const Options o = Parse(DemTable(), args);
  if (!o.Has("bundle")) throw UsageError("dem needs CRUSHER_DIR (a folder with crusher.json)");
  const fs::path crusher_dir = o.Get("bundle");
  const fs::path crusher_file = crusher_dir / "crusher.json";
  std::error_code ec;
  if (!fs::is_regular_file(crusher_file, ec))
    throw BadInput(crusher_file.string() + ": missing (a crusher folder holds crusher.json)");
  const std::string stage = o.Has("stage") ? o.Get("stage") : "all";
  if (stage != "case" && stage != "run" && stage != "map" && stage != "all")
    throw UsageError("--stage must be case, run, map or all (not '" + stage + "')");
  const bool until = o.Has("until-band");
  if (!until && (o.Has("patch") || o.Has("max-hours"))) throw UsageError("--patch and --max-hours go with --until-band");
  if (until && stage != "all") throw UsageError("--until-band runs and maps in turns: it goes with --stage all (the default)");
  dem::RunOptions run;
  run.np = o.parsed.Integer<int>("np", run.np);
  if (o.Has("mpirun")) run.mpirun = o.Get("mpirun");
  if (o.Has("liggghts")) run.liggghts = o.Get("liggghts");
  if (o.Has("progress-every")) run.progress_every_s = o.parsed.Integer<int>("progress-every", 0);
  const int windows = o.parsed.Integer<int>("windows", 0);

  nlohmann::json crusher_json;
  {
    std::ifstream in(crusher_file);
    try {
      crusher_json = nlohmann::json::parse(in);
    } catch (const nlohmann::json::exception& e) {
      throw BadInput(crusher_file.string() + ": invalid JSON (" + std::string(e.what()) + ")");
    }
  }
  const core::CrusherConfig crusher = core::LoadCrusherConfig(crusher_file);
  dem::ChamberSpec spec;
  try {
    spec = dem::ChamberFromCrusherJson(crusher_json, crusher_file.string());
  } catch (const std::invalid_argument& e) {
    throw BadInput(e.what());
  }
  const fs::path work = o.Has("work") ? fs::path(o.Get("work")) : crusher_dir / "dem";
  UntilOptions u;
  if (until) {
    u.band_mm = o.parsed.Number("until-band", 0);
    u.patch_m = o.parsed.Number("patch", crusher.thinnest_area.patches_m.front());
    u.max_hours = o.parsed.Number("max-hours", u.max_hours);
    try {
      estimate::CheckMapBandPatch(crusher, u.patch_m);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
  }

  if (stage == "case" || stage == "all") {
    dem::WriteCase(spec, work);
    const dem::CaseSteps st = dem::StepsOf(spec);
    out << "dem: case for '" << spec.name << "' in " << work.string() << ": " << 2 * spec.mesh_n_theta * spec.mesh_n_z
        << " concave faces, CSS " << std::lround(1000 * spec.closed_side_setting_m()) << " mm, " << st.total << " steps of "
        << spec.timestep_s << " s (" << spec.simulated_s << " s simulated), dumps every " << st.dump_every << " steps\n";
  }
  if (until) return DemUntil(spec, crusher, crusher_dir, work, run, windows, u, o.Flag("install"), out);
  if (stage == "run" || stage == "all") {
    const dem::RunResult r = RunStage(spec, work, run, out);
    if (!r.completed) throw BadInput(r.message);
  }
  if (stage == "map" || stage == "all") {
    MapStage(spec, work, crusher, windows, out);
    if (o.Flag("install")) InstallMap(work, crusher_dir, out);
  }
  return 0;
}

std::string OneLine(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  return s;
}

}  // namespace

int RunCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  try {
    if (args.empty())
      throw UsageError("missing command (diagnose, reconstruct, dem, plan, reline, campaigns, setting-check); see --help");
    const std::string& command = args[0];
    for (const auto& a : args) {
      if (a == "--help" || a == "-h") {
        out << Usage();
        return 0;
      }
    }
    if (command == "diagnose") return Diagnose(args, out);
    if (command == "reconstruct") return Reconstruct(args, out);
    if (command == "dem") return Dem(args, out);
    if (command == "plan") return Plan(args, out);
    if (command == "reline") return Reline(args, out);
    if (command == "campaigns") return Campaigns(args, out);
    if (command == "setting-check") return SettingCheck(args, out);
    throw UsageError("unknown command '" + command +
                     "' (diagnose, reconstruct, dem, plan, reline, campaigns, setting-check); see --help");
  } catch (const core::ConfigFileError& e) {  // a bad --config file is bad input, not a usage error
    err << "linerwatch: " << OneLine(e.what()) << "\n";
    return 1;
  } catch (const UsageError& e) {
    err << "linerwatch: " << OneLine(e.what()) << "\n";
    return 2;
  } catch (const core::InputError& e) {
    err << "linerwatch: " << e.file();
    if (e.line() > 0) err << ":" << e.line();
    err << ": " << OneLine(e.rule()) << "\n";
    return 1;
  } catch (const std::exception& e) {
    err << "linerwatch: " << OneLine(e.what()) << "\n";
    return 1;
  }
}

}  // namespace lw::cli
