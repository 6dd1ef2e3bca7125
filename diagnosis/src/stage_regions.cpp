// Diagnosis stage 7, regions (stage_regions.hpp).
#include "stage_regions.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace lw::diagnosis::detail {
namespace {

// One scan's standardised residuals of the refit baseline, its misses in mm and which cells it measured.
struct ScanResiduals {
  std::vector<double> zres, mm;
  std::vector<bool> has;
};

ScanResiduals CollectScanResiduals(const Problem& prob, const CellGrid& grid, const Eigen::MatrixXd& w_null, size_t si) {
  ScanResiduals sr{std::vector<double>(grid.cells.size(), 0.0), std::vector<double>(grid.cells.size(), 0.0),
                   std::vector<bool>(grid.cells.size(), false)};
  std::vector<double>& zres = sr.zres;
  std::vector<double>& mm = sr.mm;
  std::vector<bool>& has = sr.has;
  for (size_t i : prob.scan_obs) {
    const Obs& o = prob.obs[i];
    if (o.scan != static_cast<int>(si)) continue;
    const double e = Interp(w_null, o) - o.wear;
    zres[static_cast<size_t>(o.cell)] = e / o.sigma;
    mm[static_cast<size_t>(o.cell)] = e;
    has[static_cast<size_t>(o.cell)] = true;
  }
  return sr;
}

// The cells connected to `c` (4-neighbours, wrapping around a full circle) beyond 3 sigma of `sign`;
// labels them.
std::vector<size_t> ConnectedCells(const ScanResiduals& sr, const CellGrid& grid, bool wrap, size_t c, double sign,
                                   std::vector<int>& label) {
  const std::vector<double>& zres = sr.zres;
  const std::vector<bool>& has = sr.has;
  std::vector<size_t> stack{c}, members;
  label[c] = static_cast<int>(c);
  while (!stack.empty()) {
    const size_t cur = stack.back();
    stack.pop_back();
    members.push_back(cur);
    const long iz = static_cast<long>(cur / grid.nt), it = static_cast<long>(cur % grid.nt);
    const long nz = static_cast<long>(grid.nz), nt = static_cast<long>(grid.nt);
    const long nbr[4][2] = {{iz - 1, it}, {iz + 1, it}, {iz, it - 1}, {iz, it + 1}};
    for (const auto& nb : nbr) {
      long z = nb[0], t = nb[1];
      if (z < 0 || z >= nz) continue;
      if (t < 0 || t >= nt) {
        if (!wrap) continue;
        t = (t + nt) % nt;
      }
      const auto n = static_cast<size_t>(z * nt + t);
      if (!has[n] || label[n] >= 0 || zres[n] * sign < 3.0) continue;
      label[n] = static_cast<int>(c);
      stack.push_back(n);
    }
  }
  return members;
}

Region RegionOfCells(const std::vector<size_t>& members, const std::vector<double>& mm, const CellGrid& grid) {
  Region r;
  r.z_min_m = std::numeric_limits<double>::max();
  r.z_max_m = std::numeric_limits<double>::lowest();
  long it_min = std::numeric_limits<long>::max(), it_max = -1;
  double size = 0;
  for (size_t m : members) {
    const auto iz = static_cast<double>(m / grid.nt);
    r.z_min_m = std::min(r.z_min_m, grid.z0 + iz * grid.dz);
    r.z_max_m = std::max(r.z_max_m, grid.z0 + (iz + 1) * grid.dz);
    it_min = std::min(it_min, static_cast<long>(m % grid.nt));
    it_max = std::max(it_max, static_cast<long>(m % grid.nt));
    size += std::fabs(mm[m]);
  }
  r.theta_min_deg = std::fmod(grid.t0_deg + static_cast<double>(it_min) * grid.dt_deg, 360.0);
  r.theta_max_deg = std::fmod(grid.t0_deg + static_cast<double>(it_max + 1) * grid.dt_deg, 360.0);
  r.size_mm = Round(size / static_cast<double>(members.size()), 2);
  return r;
}

}  // namespace

std::vector<Region> ScanRegions(const ProblemSetup& setup, const Eigen::MatrixXd& w_null, size_t si, core::TimePoint installed_at,
                                core::TimePoint scan_date) {
  const CellGrid& grid = setup.grid;
  const ScanResiduals sr = CollectScanResiduals(setup.prob, grid, w_null, si);
  std::vector<Region> regions;
  std::vector<int> label(grid.cells.size(), -1);
  const bool wrap = setup.fields.theta_span_deg >= 359.0;
  for (size_t c = 0; c < grid.cells.size(); ++c) {
    if (!sr.has[c] || std::fabs(sr.zres[c]) < 3.0 || label[c] >= 0) continue;
    const double sign = sr.zres[c] > 0 ? 1.0 : -1.0;
    const std::vector<size_t> members = ConnectedCells(sr, grid, wrap, c, sign, label);
    double peak = 0;
    for (size_t m : members) peak = std::max(peak, std::fabs(sr.zres[m]));
    if (members.size() < 2 && peak < 5.0) continue;
    Region r = RegionOfCells(members, sr.mm, grid);
    r.from = installed_at;
    r.to = scan_date;
    r.sign = sign > 0 ? "over" : "under";
    r.source = "scan:" + setup.scans[si].file;
    regions.push_back(r);
  }
  return regions;
}

std::vector<Region> SensorRegions(const ProblemSetup& setup, const NullModel& null, core::TimePoint installed_at) {
  const Problem& prob = setup.prob;
  const Eigen::MatrixXd& w_null = null.w;
  auto to_time = [&](double days) { return core::AddDays(installed_at, days); };
  std::vector<Region> regions;
  for (const SensorData& s : setup.sensors) {
    if (!s.usable) continue;
    const auto& list = prob.sensor_obs[static_cast<size_t>(s.usable_index)];
    const double u = null.fit.u[static_cast<size_t>(s.usable_index)];
    size_t k = 0;
    while (k < list.size()) {
      const Obs& o = prob.obs[list[k]];
      const double e = Interp(w_null, o) * (1.0 + u) - o.wear;
      if (std::fabs(e / o.sigma) < 3.0) {
        ++k;
        continue;
      }
      const double sign = e > 0 ? 1.0 : -1.0;
      size_t end = k;
      double size = 0;
      while (end < list.size()) {
        const Obs& oe = prob.obs[list[end]];
        const double ee = Interp(w_null, oe) * (1.0 + u) - oe.wear;
        if (ee * sign / oe.sigma < 3.0) break;
        size += std::fabs(ee);
        ++end;
      }
      if (end - k >= 3) {
        Region r;
        r.z_min_m = s.z - 0.02;
        r.z_max_m = s.z + 0.02;
        r.theta_min_deg = std::fmod(s.theta - 1.0 + 360.0, 360.0);
        r.theta_max_deg = std::fmod(s.theta + 1.0, 360.0);
        r.from = to_time(prob.obs[list[k]].t);
        r.to = to_time(prob.obs[list[end - 1]].t);
        r.sign = sign > 0 ? "over" : "under";
        r.size_mm = Round(size / static_cast<double>(end - k), 2);
        r.source = "sensor:" + s.id;
        regions.push_back(r);
      }
      k = std::max(end, k + 1);
    }
  }
  return regions;
}

std::vector<Region> FindRegions(const core::Bundle& bundle, const ProblemSetup& setup, const NullModel& null) {
  std::vector<Region> regions;
  for (size_t si = 0; si < setup.scans.size(); ++si)
    for (Region& r : ScanRegions(setup, null.w, si, bundle.crusher.installed_at, bundle.scans[si].date))
      regions.push_back(std::move(r));
  for (Region& r : SensorRegions(setup, null, bundle.crusher.installed_at)) regions.push_back(std::move(r));
  std::stable_sort(regions.begin(), regions.end(), [](const Region& a, const Region& b) { return a.size_mm > b.size_mm; });
  if (regions.size() > 30) regions.resize(30);
  return regions;
}

}  // namespace lw::diagnosis::detail
