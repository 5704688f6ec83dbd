#include "core/optim/results_export.h"

#include <fstream>

#include "core/error.h"
#include "core/io/job_io.h"
#include "core/diff/parameters.h"
#include "core/job/problem.h"
#include "core/optim/results_io.h"
#include "core/diff/parameter_kind.h"

namespace invr {

namespace fs = std::filesystem;
namespace v1 = invr::v1;

namespace {


// The exported job: the same optimisation over the exported scene.
// resultsDir empty: the job as given (its scene as described), initial values and targets kept.
v1::JobSpec exportedJob(const v1::JobSpec& job, const Problem& p, const std::vector<float>& theta, const fs::path& resultsDir,
                        const fs::path& xml, const std::vector<std::pair<std::string, std::string>>& renamed,
                        std::vector<std::string>& notes) {
  const bool asGiven = resultsDir.empty();
  v1::JobSpec out = job;
  out.mutable_mitsuba()->set_path(xml.filename().string());  // replaces the zoo name or inline scene
  if (!job.has_optimization()) return out;
  v1::OptimizationSpec& o = *out.mutable_optimization();
  o.clear_parameters();
  const auto& slots = p.params.slots();
  // Results of a synthetic job: the exported scene holds the optimised values, so the truth the
  // original job's scene held goes into the job (truth_values): its targets are rendered from it
  // and its parameter error measured against it, as in the run it continues. Shape parameters
  // cannot carry theirs: their values are relative to the shape's geometry, which the export
  // writes where the run left it (a recovered mesh, a recovered pose): such a job goes on against
  // the run's target images instead, with no truth.
  bool shapes = false;
  for (const ParameterSlot& s : slots)
    shapes = shapes || s.kind->relativeToGeometry();
  const bool keepTruth = !asGiven && job.optimization().targets_size() == 0 && !shapes;
  for (int i = 0; i < job.optimization().parameters_size() && size_t(i) < slots.size(); ++i) {
    const ParameterSlot& s = slots[size_t(i)];
    v1::ParameterSpec ps = job.optimization().parameters(i);
    if (s.group >= 0) {
      notes.push_back("parameter '" + ps.name() + "' moves a group of shapes, which a Mitsuba scene cannot hold: left out of the job");
      continue;
    }
    // The scene's own names: a Mitsuba key or alias as given (s.name) may not survive the export.
    std::string name = invrParameterName(*p.scene, s.name);
    for (const auto& [from, to] : renamed)
      if (name.rfind(from, 0) == 0) name = to + name.substr(from.size());
    ps.set_name(name);
    if (asGiven) {  // the scene holds the truth: the job starts where it did
      *o.add_parameters() = std::move(ps);
      continue;
    }
    ps.clear_initial();
    ps.clear_initial_values();
    ps.clear_initial_mesh();
    ps.clear_truth_values();
    if (s.kind->changesNoiseOnly())  // not part of the scene: the job carries them
      for (uint32_t k = 0; k < s.size; ++k) ps.add_initial_values(double(theta[s.offset + k]));
    else if (keepTruth)
      for (uint32_t k = 0; k < s.size; ++k) ps.add_truth_values(double(p.truth[s.offset + k]));
    *o.add_parameters() = std::move(ps);
  }
  if (asGiven) {
    if (job.optimization().targets_size() > 0)
      notes.push_back("the job's target images keep their paths: copy them beside the exported job, or give them again as optimization.targets");
    return out;
  }
  if (job.optimization().targets_size() > 0) {
    o.clear_targets();
    o.clear_target_masks();
    notes.push_back("the exported job has no truth (the run's targets were images): give them again as optimization.targets to optimise "
                    "further; until then it renders its targets from the exported, optimised scene");
  } else if (keepTruth) {
    notes.push_back("the exported job keeps the run's truth (optimization.parameters[].truth_values): it starts at the optimised values, "
                    "renders its targets from the truth and measures its parameter error against it, as the run did");
  } else {
    // Rendered targets: the results hold them for the first views. With all of them, the job
    // goes on against the same images; otherwise it would render new targets from the
    // optimised scene.
    const size_t views = p.scene->cameras.size();
    bool all = true;
    for (size_t v = 0; v < views; ++v) all = all && fs::exists(resultsDir / ("target_view" + std::to_string(v) + ".exr"));
    notes.push_back("the exported job has no truth (shape and camera parameters are relative to the shapes' geometry and the cameras, "
                    "which the export writes as recovered): it goes on against the run's target images");
    if (all) {
      const fs::path dir = xml.has_parent_path() ? xml.parent_path() : fs::path(".");
      fs::create_directories(dir / "targets");
      for (size_t v = 0; v < views; ++v) {
        const std::string name = "targets/target_view" + std::to_string(v) + ".exr";
        fs::copy_file(resultsDir / ("target_view" + std::to_string(v) + ".exr"), dir / name, fs::copy_options::overwrite_existing);
        o.add_targets()->set_path(name);
      }
    } else {
      notes.push_back("the results do not hold a target image (target_view<k>.exr) for each of the " + std::to_string(views) +
                      " views: the job renders its targets from the optimised scene; give optimization.targets to optimise further");
    }
  }
  return out;
}

}  // namespace

namespace {

ResultsExport writeExport(const v1::JobSpec& job, Problem& p, const std::vector<float>& theta, const fs::path& resultsDir,
                          const fs::path& xml) {
  MitsubaExportOptions mo;
  mo.spp = job.render().spp() > 0 ? job.render().spp() : 16;
  mo.maxDepth = std::max(1, p.gradient.maxDepth);
  mo.russianRouletteDepth = p.gradient.russianRouletteDepth;
  ResultsExport out;
  out.scene = exportMitsubaScene(*p.scene, xml, mo);
  out.notes = out.scene.notes;
  const v1::JobSpec exported = exportedJob(job, p, theta, resultsDir, xml, out.scene.renamed, out.notes);
  out.job = xml;
  out.job.replace_extension(".json");
  std::ofstream f(out.job);
  if (!f) throw InputError("cannot write '" + out.job.string() + "'");
  f << jobToJson(exported);
  if (!f.flush()) throw InputError("cannot write '" + out.job.string() + "'");
  return out;
}

}  // namespace

ResultsExport exportResults(const fs::path& resultsDir, const fs::path& xml, const AssetResolver& assets) {
  if (!fs::is_directory(resultsDir)) throw InputError("'" + resultsDir.string() + "': not a results folder");
  const fs::path jobFile = resultsDir / "job.json";
  if (!fs::exists(jobFile))
    throw InputError("'" + resultsDir.string() + "' has no job.json (results of invr run, fetch and optimize have it since 0.9.0)");
  const v1::JobSpec job = loadJobFile(jobFile);
  if (job.has_mitsuba()) throw InputError("'" + jobFile.string() + "': its scene is still a Mitsuba file reference; expected the imported scene");
  // The scene is what is exported: the targets are not needed to build it.
  v1::JobSpec buildable = job;
  buildable.mutable_optimization()->clear_targets();
  buildable.mutable_optimization()->clear_target_masks();
  Problem p = buildProblem(buildable, assets);  // with a BVH: writing shape motion refits it
  std::vector<float> theta = p.initial;
  readParameters(resultsDir, p.params, theta);
  p.params.write(theta, *p.scene);
  return writeExport(job, p, theta, resultsDir, xml);
}

ResultsExport exportJob(const v1::JobSpec& job, const fs::path& xml, const AssetResolver& assets) {
  if (job.has_mitsuba()) throw InputError("the job's scene is still a Mitsuba file reference; expected the imported scene");
  v1::JobSpec buildable = job;
  buildable.mutable_optimization()->clear_targets();
  buildable.mutable_optimization()->clear_target_masks();
  Problem p = buildProblem(buildable, assets);
  p.params.write(p.truth, *p.scene);
  for (const auto& t : p.truthMeshes)  // a shape started from another mesh: its truth is exported
    if (t.replaced) p.scene->replaceMesh(t.mesh, t.geometry);
  return writeExport(job, p, p.truth, {}, xml);
}

}  // namespace invr
