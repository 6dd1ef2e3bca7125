#pragma once
/// Diagnosis stage 1, problem set-up: bundle -> map fields, analysed sensors (data quality,
/// loop-crossing events), the rows anchored by usable sensors, the time grid with the throughput
/// series, and the observations (sensor events, scan cells) with their measurement noise.
#include <string>
#include <vector>

#include "diagnosis/diagnose.hpp"
#include "fields.hpp"
#include "model_fit.hpp"
#include "sensor_quality.hpp"

namespace lw::diagnosis::detail {

/// One configured sensor: position, data-quality analysis and map fields.
struct SensorData {
  size_t config_index = 0;
  std::string id;
  std::string row;
  double z = 0, theta = 0, thickness = 0;
  SensorAnalysis analysis;
  PointField field;
  bool usable = false;
  int usable_index = -1;  ///< index among usable sensors
  double sigma_u = 0;
};

/// Linear interpolation of the row scales between the centres of the anchored rows.
struct Interpolator {
  std::vector<double> centres;  ///< z of anchor rows (sorted)
  std::vector<int> params;      ///< parameter index of each centre
  void Weights(double z, int& a, int& b, double& wa) const;
};

/// The wear model's point for map fields `f` at a liner of half thickness `half_thickness`.
ModelPoint MakePoint(const MapFields& fields, const Interpolator& interp, const PointField& f, double half_thickness);

/// The time grid and its throughput x abrasiveness series (1 when not identifiable).
struct TimeSetup {
  TimeGrid grid;
  double t_obs_end = 0;  ///< last used sensor reading, days
  bool throughput_available = false;
  double throughput_cv = 0;
};

struct ProblemSetup {
  MapFields fields;
  std::vector<SensorData> sensors;  ///< every configured sensor, in configuration order
  Interpolator interp;
  std::vector<std::string> anchor_rows;  ///< rows holding a usable sensor, bottom to top (one row scale each)
  TimeSetup time;
  Problem prob;  ///< sigma of scan cells is 0 until the baseline stage's noise model sets it
  CellGrid grid;
  std::vector<ScanCells> scans;
  bool Diagnosable() const { return !interp.centres.empty(); }
};

/// Map fields and the map's notes/noise entries.
MapFields DescribeMap(const core::Bundle& bundle, DiagnosisResult& result);
/// Every configured sensor analysed; its faults go to result.data_quality.
std::vector<SensorData> AnalyseSensors(const core::Bundle& bundle, const MapFields& fields, DiagnosisResult& result);
/// The rows holding at least one usable sensor, by height; fills `interp`.
std::vector<std::string> AnchorRows(const core::CrusherConfig& crusher, const std::vector<SensorData>& sensors,
                                    Interpolator& interp);
/// Time grid over the readings, scans and prediction time; throughput from operations.csv (notes when skipped).
TimeSetup BuildTimeGrid(const core::Bundle& bundle, const std::vector<SensorData>& sensors, const DiagnoseOptions& options,
                        DiagnosisResult& result);
/// Usable sensors' crossing events as observations (assigns usable_index); then their measured excess scatter.
void AddSensorObservations(const MapFields& fields, const Interpolator& interp, std::vector<SensorData>& sensors, Problem& prob,
                           DiagnosisResult& result);
/// Scans projected on the cell grid; each measured cell an observation.
std::vector<ScanCells> AddScanObservations(const core::Bundle& bundle, const MapFields& fields, const Interpolator& interp,
                                           const CellGrid& grid, Problem& prob, DiagnosisResult& result);

/// The whole stage. When no sensor is usable the result holds a note and Diagnosable() is false
/// (the later stages must not run).
ProblemSetup SetUpProblem(const core::Bundle& bundle, const DiagnoseOptions& options, DiagnosisResult& result);

}  // namespace lw::diagnosis::detail
