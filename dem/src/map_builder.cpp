#include "dem/map_builder.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>

#include "core/atomic_file.hpp"
#include "core/median.hpp"
#include "core/wear_map.hpp"
#include "dem/case_writer.hpp"
#include "dem/runner.hpp"
#include "dem/series.hpp"

namespace lw::dem {
namespace {

namespace fs = std::filesystem;

struct Sample {
  double t, n, m_chamber, m_hopper, m_total, m_inserted;
};

std::vector<Sample> ReadSeries(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": missing (was the case run?)");
  std::vector<Sample> out;
  std::string line;
  size_t n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (line.empty() || !(std::isdigit(static_cast<unsigned char>(line[0])) || line[0] == '-')) continue;
    std::istringstream ls(line);
    Sample s{};
    if (!(ls >> s.t >> s.n >> s.m_chamber >> s.m_hopper >> s.m_total >> s.m_inserted))
      throw std::runtime_error(file.string() + ":" + std::to_string(n) + ": expected 6 numbers");
    if (!out.empty() && s.t <= out.back().t) continue;  // a resumed run may repeat a sample
    out.push_back(s);
  }
  return out;
}

// Index of each face of `m` in `ref`, matched by centroid (LIGGGHTS may gather faces in another
// order from run to run, e.g. after a restart on another rank count).
std::vector<size_t> MatchFaces(const core::WearMap& ref, const core::WearMap& m, const std::string& file) {
  if (m.face_count() != ref.face_count())
    throw std::runtime_error(file + ": " + std::to_string(m.face_count()) + " faces, the first dump has " +
                             std::to_string(ref.face_count()));
  std::vector<size_t> idx(m.face_count());
  bool same = true;
  for (size_t i = 0; i < m.face_count() && same; ++i) same = (m.centroids[i] - ref.centroids[i]).norm() < 1e-6;
  if (same) {
    for (size_t i = 0; i < idx.size(); ++i) idx[i] = i;
    return idx;
  }
  auto key = [](const Eigen::Vector3d& c) {
    std::ostringstream k;
    k << std::llround(c.x() * 1e5) << ',' << std::llround(c.y() * 1e5) << ',' << std::llround(c.z() * 1e5);
    return k.str();
  };
  std::map<std::string, size_t> where;
  for (size_t i = 0; i < ref.face_count(); ++i) where[key(ref.centroids[i])] = i;
  for (size_t i = 0; i < m.face_count(); ++i) {
    auto it = where.find(key(m.centroids[i]));
    if (it == where.end()) throw std::runtime_error(file + ": face " + std::to_string(i) + " is not a face of the first dump");
    idx[i] = it->second;
  }
  return idx;
}

Eigen::VectorXd Reorder(const Eigen::VectorXd& v, const std::vector<size_t>& idx) {
  Eigen::VectorXd out(v.size());
  for (size_t i = 0; i < idx.size(); ++i) out[static_cast<Eigen::Index>(idx[i])] = v[static_cast<Eigen::Index>(i)];
  return out;
}

// The dump's mesh with shared points (LIGGGHTS repeats each triangle's points).
core::WearMap SharedPointMesh(const core::WearMap& dump) {
  core::WearMap m;
  std::map<std::tuple<long long, long long, long long>, uint32_t> ids;
  for (const auto& f : dump.faces) {
    std::array<uint32_t, 3> nf{};
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d& p = dump.points[f[static_cast<size_t>(k)]];
      const auto key = std::make_tuple(std::llround(p.x() * 1e7), std::llround(p.y() * 1e7), std::llround(p.z() * 1e7));
      auto it = ids.find(key);
      if (it == ids.end()) {
        it = ids.emplace(key, static_cast<uint32_t>(m.points.size())).first;
        m.points.push_back(p);
      }
      nf[static_cast<size_t>(k)] = it->second;
    }
    m.faces.push_back(nf);
  }
  m.wear = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(m.faces.size()));
  m.ComputeGeometry();
  return m;
}

/// From the first LIGGGHTS log with a version line: `linerwatch dem`'s log.<n>.liggghts in order, then
/// run.slurm's log.slurm-<job>.liggghts (a case run on a cluster has only those).
std::string LiggghtsVersion(const fs::path& case_dir) {
  std::vector<fs::path> logs;
  for (int a = 1; fs::exists(case_dir / ("log." + std::to_string(a) + ".liggghts")); ++a)
    logs.push_back(case_dir / ("log." + std::to_string(a) + ".liggghts"));
  std::vector<fs::path> others;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(case_dir, ec)) {
    const std::string n = e.path().filename().string();
    if (n.rfind("log.slurm-", 0) == 0 && n.size() > 9 && n.compare(n.size() - 9, 9, ".liggghts") == 0) others.push_back(e.path());
  }
  std::sort(others.begin(), others.end());
  logs.insert(logs.end(), others.begin(), others.end());
  for (const fs::path& log : logs) {
    std::ifstream in(log);
    if (!in) continue;
    std::string line;
    std::getline(in, line);
    const auto p = line.find("Version ");
    if (p != std::string::npos) {
      const auto e = line.find(',', p);
      std::string v = line.substr(p + 8, e == std::string::npos ? std::string::npos : e - p - 8);
      const auto d = v.rfind(' ');
      return d == std::string::npos ? v : v.substr(d + 1);
    }
  }
  return "unknown";
}

nlohmann::json Attempts(const fs::path& case_dir) {
  nlohmann::json a = nlohmann::json::array();
  std::ifstream in(case_dir / "attempts.txt");
  int attempt = 0, np = 0;
  long from = 0;
  double wall = 0;
  std::string state;
  while (in >> attempt >> from >> wall >> np >> state)
    a.push_back({{"attempt", attempt}, {"from_step", from}, {"wall_s", wall}, {"np", np}, {"state", state}});
  return a;
}

// The dumps of the steady span (the first one at or after its start) and their split into windows.
struct Span {
  std::vector<double> dump_t;  // time of every dump, s
  size_t first = 0, last = 0;  // indices of the span's first and last dump
  double seconds = 0;          // from the first to the last dump
  double min_window_s = 0;
  int k = 0;  // windows
  std::vector<std::pair<size_t, size_t>> win;
};

Span ChooseSpan(const ChamberSpec& spec, const fs::path& case_dir, const std::vector<long>& dump_steps,
                const SteadyWindow& steady, int windows) {
  Span sp;
  for (long s : dump_steps) sp.dump_t.push_back(static_cast<double>(s) * spec.timestep_s);
  while (sp.first < sp.dump_t.size() && sp.dump_t[sp.first] < steady.t_start - 1e-9) ++sp.first;
  sp.last = sp.dump_t.size() - 1;
  sp.seconds = sp.first < sp.dump_t.size() ? sp.dump_t[sp.last] - sp.dump_t[sp.first] : 0;
  const double gyration_s = 60.0 / spec.speed_rpm;
  sp.min_window_s = std::max(3 * gyration_s, spec.dump_interval_s);
  const int requested = windows > 0 ? windows : spec.windows;
  sp.k = ChooseWindowCount(sp.seconds, sp.min_window_s, requested);
  if (sp.k > 0 && static_cast<long>(sp.last - sp.first) < sp.k) sp.k = static_cast<int>(sp.last - sp.first);
  if (sp.k < 2) {
    // What would be enough: the windows after the span's first dump, rounded up to a dump, so the
    // user raises simulated_s once instead of by trial (the run resumes from its last restart).
    const int want = requested > 0 ? requested : 2;
    const double t_first = sp.first < sp.dump_t.size() ? sp.dump_t[sp.first] : steady.t_start;
    const double need = std::ceil((t_first + want * sp.min_window_s) / spec.dump_interval_s - 1e-9) * spec.dump_interval_s;
    char b[400];
    std::snprintf(b, sizeof b,
                  ": the steady span (%.2f s from t = %.2f s) holds fewer than %d windows of %.2f s; raise "
                  "chamber.simulated_s to at least %.1f s (now %.1f s) and run again (it resumes; a longer run can "
                  "move the steady start, so allow a little more)",
                  sp.seconds, steady.t_start, want, sp.min_window_s, need, spec.simulated_s);
    throw std::runtime_error(case_dir.string() + b);
  }
  sp.win = SplitWindows(sp.first, sp.last, sp.k);
  return sp;
}

// The span's dumps, faces in the first one's order: wear is cumulative, stresses are per-dump averages.
struct Dumps {
  core::WearMap ref;  // the span's first dump
  std::vector<Eigen::VectorXd> cum, sn, ss;
};

Dumps LoadDumps(const fs::path& post, const std::vector<long>& dump_steps, const Span& sp) {
  const auto load = [&](size_t i) {
    const fs::path f = post / ("concave_" + std::to_string(dump_steps[i]) + ".vtk");
    return core::LoadWearMap(f);
  };
  Dumps d{load(sp.first), {}, {}, {}};
  if (!d.ref.has_normal_stress() || !d.ref.has_shear_stress())
    throw std::runtime_error(post.string() + ": dumps lack normal/shear stress (the case must dump `stress wear`)");
  d.cum.resize(sp.dump_t.size()), d.sn.resize(sp.dump_t.size()), d.ss.resize(sp.dump_t.size());
  d.cum[sp.first] = d.ref.wear, d.sn[sp.first] = d.ref.normal_stress, d.ss[sp.first] = d.ref.shear_stress;
  for (size_t i = sp.first + 1; i <= sp.last; ++i) {
    const core::WearMap m = load(i);
    const auto idx = MatchFaces(d.ref, m, "concave_" + std::to_string(dump_steps[i]) + ".vtk");
    d.cum[i] = Reorder(m.wear, idx), d.sn[i] = Reorder(m.normal_stress, idx), d.ss[i] = Reorder(m.shear_stress, idx);
  }
  return d;
}

// Per face: the wear of each window and of the span, its standard error, and the stresses averaged.
struct Fields {
  Eigen::Index n = 0;  // faces
  std::vector<Eigen::VectorXd> w_inc, w_sn;
  Eigen::VectorXd total, stderr_total, sn_avg, ss_avg;
};

Fields SumWindows(const Dumps& d, const Span& sp) {
  Fields f;
  const Eigen::Index n = f.n = static_cast<Eigen::Index>(d.ref.face_count());
  f.total = Eigen::VectorXd::Zero(n), f.sn_avg = Eigen::VectorXd::Zero(n), f.ss_avg = Eigen::VectorXd::Zero(n);
  for (const auto& [b, e] : sp.win) {
    f.w_inc.push_back(d.cum[e] - d.cum[b]);
    Eigen::VectorXd a = Eigen::VectorXd::Zero(n);
    for (size_t i = b + 1; i <= e; ++i) a += d.sn[i];
    f.w_sn.push_back(a / static_cast<double>(e - b));
    f.total += f.w_inc.back();
  }
  for (size_t i = sp.first + 1; i <= sp.last; ++i) f.sn_avg += d.sn[i], f.ss_avg += d.ss[i];
  f.sn_avg /= static_cast<double>(sp.last - sp.first), f.ss_avg /= static_cast<double>(sp.last - sp.first);
  // Standard error of the total: sqrt(K) x the sample sd of the K window increments.
  f.stderr_total = Eigen::VectorXd::Zero(n);
  const Eigen::VectorXd mean_inc = f.total / sp.k;
  for (const auto& w : f.w_inc) f.stderr_total += (w - mean_inc).cwiseAbs2();
  f.stderr_total = (f.stderr_total / (sp.k - 1)).cwiseSqrt() * std::sqrt(static_cast<double>(sp.k));
  return f;
}

// The map and the per-window map into `out_dir`; returns their mesh (shared points, the span's wear).
core::WearMap WriteMaps(const ChamberSpec& spec, const fs::path& case_dir, const fs::path& out_dir, const Span& sp,
                        const Fields& f, const core::WearMap& ref) {
  const int k = sp.k;
  core::WearMap out = SharedPointMesh(ref);
  out.wear = f.total;
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  char title[256];
  std::snprintf(title, sizeof title, "linerwatch dem %s windows=%d window_s=%.3f steady_from_s=%.3f steady_to_s=%.3f liggghts=%s",
                spec.name.c_str(), k, sp.seconds / k, sp.dump_t[sp.first], sp.dump_t[sp.last], LiggghtsVersion(case_dir).c_str());
  core::WriteWearMapVtk(out_dir / MapFiles::kMap, out,
                        {{"wear", &f.total},
                         {"wear_stderr", &f.stderr_total},
                         {"normal_stress_average", &f.sn_avg},
                         {"shear_stress_average", &f.ss_avg}},
                        title);
  std::vector<std::string> names;
  std::vector<std::pair<std::string, const Eigen::VectorXd*>> arrays = {{"wear", &f.total}};  // loads as a map too
  for (int i = 0; i < k; ++i) names.push_back("wear_w" + std::to_string(i + 1));
  for (int i = 0; i < k; ++i) names.push_back("normal_stress_w" + std::to_string(i + 1));
  for (int i = 0; i < k; ++i) arrays.push_back({names[static_cast<size_t>(i)], &f.w_inc[static_cast<size_t>(i)]});
  for (int i = 0; i < k; ++i) arrays.push_back({names[static_cast<size_t>(k + i)], &f.w_sn[static_cast<size_t>(i)]});
  core::WriteWearMapVtk(out_dir / MapFiles::kWindows, out, arrays, title);
  return out;
}

// Steady span and flow.
nlohmann::json SteadyJson(const std::vector<Sample>& series, const SteadyWindow& steady, const Span& sp) {
  const std::vector<double>& dump_t = sp.dump_t;
  double flow_tph = 0, hopper_min = 1e300;
  {
    const Sample* a = nullptr;
    const Sample* b = nullptr;
    for (const auto& s : series)
      if (s.t >= dump_t[sp.first] - 1e-9 && s.t <= dump_t[sp.last] + 1e-9) {
        if (!a) a = &s;
        b = &s;
        hopper_min = std::min(hopper_min, s.m_hopper);
      }
    if (a && b && b->t > a->t) flow_tph = ((b->m_inserted - b->m_total) - (a->m_inserted - a->m_total)) / (b->t - a->t) * 3.6;
  }
  return {{"from_s", dump_t[sp.first]},
          {"to_s", dump_t[sp.last]},
          {"chamber_mass_t", steady.level / 1000.0},
          {"band_t", steady.band / 1000.0},
          {"drift", steady.drift},
          {"note", steady.reason},
          {"mass_flow_tph", flow_tph},
          {"hopper_min_t", hopper_min / 1000.0},
          {"choke_fed", hopper_min > 0.05 * steady.level}};
}

// Rows: area-weighted mean intensity, spread, edge outliers, noise; and the faces over 10x their
// row's mean, all rows together.
struct RowStats {
  nlohmann::json rows = nlohmann::json::array();
  size_t outliers = 0, edge_outliers = 0;
};

RowStats Rows(const ChamberSpec& spec, const std::vector<core::Row>& rows, const core::WearMap& out, const Fields& f) {
  const Eigen::Index n = f.n;
  const Eigen::VectorXd& total = f.total;
  RowStats st;
  nlohmann::json& jrows = st.rows;
  std::vector<double> means;
  const double band_h = spec.height_m() / spec.mesh_n_z;
  for (const auto& row : rows) {
    double aw = 0, a = 0;
    std::vector<double> vals, rel_se;
    for (Eigen::Index i = 0; i < n; ++i) {
      if (out.z[i] < row.z_min_m || out.z[i] >= row.z_max_m) continue;
      aw += out.areas[i] * total[i], a += out.areas[i];
      vals.push_back(total[i]);
      if (total[i] > 0) rel_se.push_back(f.stderr_total[i] / total[i]);
    }
    const double mean = a > 0 ? aw / a : 0;
    double var = 0;
    for (double v : vals) var += (v - mean) * (v - mean);
    const double cv = vals.size() > 1 && mean > 0 ? std::sqrt(var / static_cast<double>(vals.size() - 1)) / mean : 0;
    size_t row_out = 0;
    for (Eigen::Index i = 0; i < n; ++i) {
      if (out.z[i] < row.z_min_m || out.z[i] >= row.z_max_m || mean <= 0) continue;
      if (total[i] > 10 * mean) {
        ++row_out;
        const bool edge = out.z[i] < band_h || out.z[i] > spec.height_m() - band_h;
        st.edge_outliers += edge ? 1 : 0;
      }
    }
    st.outliers += row_out;
    means.push_back(mean);
    jrows.push_back({{"row", row.name},
                     {"z_min_m", row.z_min_m},
                     {"z_max_m", row.z_max_m},
                     {"faces", vals.size()},
                     {"mean_wear", mean},
                     {"cv", cv},
                     {"median_rel_stderr", core::UpperMedian(rel_se)},
                     {"faces_over_10x_mean", row_out}});
  }
  const double lowest = *std::min_element(means.begin(), means.end());
  for (size_t r = 0; r < jrows.size(); ++r) jrows[r]["ratio"] = lowest > 0 ? means[r] / lowest : 0.0;
  return st;
}

// Validation summary.
nlohmann::json Summary(const ChamberSpec& spec, const fs::path& case_dir, const CaseSteps& steps,
                       const std::vector<Sample>& series, const SteadyWindow& steady, const Span& sp, const Fields& f,
                       const core::WearMap& out, std::vector<core::Row> rows) {
  const Eigen::Index n = f.n;
  const Eigen::VectorXd& total = f.total;
  if (rows.empty()) {
    const double h = spec.height_m();
    rows = {{"LDWN", 0, h / 3}, {"LMID", h / 3, 2 * h / 3}, {"LUP", 2 * h / 3, h}};
  }
  nlohmann::json summary;
  summary["name"] = spec.name;
  summary["liggghts"] = LiggghtsVersion(case_dir);
  summary["faces"] = out.face_count();
  summary["steps"] = steps.total;
  summary["simulated_s"] = static_cast<double>(steps.total) * spec.timestep_s;
  summary["attempts"] = Attempts(case_dir);
  double wall = 0;
  for (const auto& a : summary["attempts"]) wall += a["wall_s"].get<double>();
  summary["runtime_s"] = wall;
  summary["steady"] = SteadyJson(series, steady, sp);
  summary["windows"] = {{"count", sp.k}, {"window_s", sp.seconds / sp.k}, {"min_window_s", sp.min_window_s}};
  size_t zero_faces = 0;
  for (Eigen::Index i = 0; i < n; ++i) zero_faces += total[i] <= 0 ? 1 : 0;
  const RowStats st = Rows(spec, rows, out, f);
  summary["rows"] = st.rows;
  std::vector<double> rel;
  for (Eigen::Index i = 0; i < n; ++i)
    if (total[i] > 0) rel.push_back(f.stderr_total[i] / total[i]);
  summary["faces_zero"] = zero_faces;
  summary["faces_zero_fraction"] = static_cast<double>(zero_faces) / static_cast<double>(n);
  summary["faces_over_10x_row_mean"] = st.outliers;
  summary["edge_faces_over_10x_row_mean"] = st.edge_outliers;
  summary["median_rel_stderr"] = core::UpperMedian(rel);
  // Correlation of wear with normal stress across faces (shared sampling noise shows here too).
  {
    const double mw = total.mean(), ms = f.sn_avg.mean();
    const double cov = ((total.array() - mw) * (f.sn_avg.array() - ms)).sum();
    const double den = std::sqrt((total.array() - mw).square().sum() * (f.sn_avg.array() - ms).square().sum());
    summary["corr_wear_normal_stress"] = den > 0 ? cov / den : 0.0;
  }
  summary["chamber"] = ToJson(spec);
  return summary;
}

}  // namespace

nlohmann::json BuildMap(const ChamberSpec& spec, const fs::path& case_dir, std::vector<core::Row> rows, const fs::path& out_dir,
                        int windows) {
  const CaseSteps steps = StepsOf(spec);
  const fs::path post = case_dir / CaseLayout::kDumpDir;
  const auto dump_steps = StepsInFolder(post, "concave_", ".vtk");
  if (dump_steps.empty() || dump_steps.back() < steps.total)
    throw std::runtime_error(post.string() + ": the run is not complete (last dump at step " +
                             std::to_string(dump_steps.empty() ? 0 : dump_steps.back()) + " of " + std::to_string(steps.total) +
                             "); run `linerwatch dem` again to resume it");
  const auto series = ReadSeries(case_dir / CaseLayout::kMassSeries);
  std::vector<double> t, m;
  for (const auto& s : series) t.push_back(s.t), m.push_back(s.m_chamber);
  const SteadyWindow steady = DetectSteadyWindow(t, m);
  if (!steady.found)
    throw std::runtime_error((case_dir / CaseLayout::kMassSeries).string() + ": no steady, choke-fed span: " + steady.reason);

  const Span sp = ChooseSpan(spec, case_dir, dump_steps, steady, windows);
  const Dumps dumps = LoadDumps(post, dump_steps, sp);
  const Fields fields = SumWindows(dumps, sp);
  const core::WearMap out = WriteMaps(spec, case_dir, out_dir, sp, fields, dumps.ref);
  const nlohmann::json summary = Summary(spec, case_dir, steps, series, steady, sp, fields, out, std::move(rows));
  // Text read from the case (the log's version line, attempts.txt's states) need not be UTF-8: replace
  // what is not, rather than fail the whole map on it (found by fuzz/dem_case).
  const std::string text = summary.dump(2, ' ', false, nlohmann::json::error_handler_t::replace);
  core::WriteFileAtomically(out_dir / MapFiles::kSummary, text + "\n");
  return nlohmann::json::parse(text);  // what was written, so that callers never meet the raw bytes
}

}  // namespace lw::dem
