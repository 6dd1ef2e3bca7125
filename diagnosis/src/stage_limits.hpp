#pragma once
/// Detection limits (JSON `limits`, docs/diagnosis.md "Detection limits"): per tested effect, the
/// smallest strength these data would have shown, from the fit's information at its noise.
#include <vector>

#include "diagnosis/diagnose.hpp"
#include "stage_hypotheses.hpp"

namespace lw::diagnosis::detail {

/// One DetectionLimit per single effect tried (the smaller over profile_evolution's two forms);
/// `named` from `findings`. `last_day`: the data's last observation.
std::vector<DetectionLimit> DetectionLimits(const Hypotheses& h, double log_n, double map_harmonic1_sd,
                                            const std::vector<Finding>& findings, double last_day);

}  // namespace lw::diagnosis::detail
