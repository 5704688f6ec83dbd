#include "core/diff/variance_visitor.h"

namespace invr {

namespace {

double dotRgb(Rgb a, Rgb b) { return double(a.x) * b.x + double(a.y) * b.y + double(a.z) * b.z; }

}  // namespace

void VarianceVisitor::addPdfGradient(int material, Vec2 uv, const PdfDerivatives& pdf, double coefLog) {
  if (coefLog == 0.0 || !(pdf.pdf > 0.f)) return;
  // Coefficient on d log pdf = coefLog / pdf on d pdf; addBsdfGradient maps (d albedo_c, d alpha)
  // onto the material's parameters (alpha's adjoint is the channel sum: only x carries it).
  BsdfDerivatives dd;
  dd.dAlbedo = pdf.dAlbedo;
  dd.dAlpha = Rgb(pdf.dAlpha, 0.f, 0.f);
  addBsdfGradient(params_, scene_, material, uv, dd, Rgb(float(coefLog / double(pdf.pdf))), grad_);
}

void VarianceVisitor::addSelectionGradient() {
  const size_t n = scene_.lights.size();
  bool any = false;
  for (double c : s_.selection) any = any || c != 0.0;
  if (!any) return;
  thread_local std::vector<double> out;
  out.assign(n, 0.0);
  if (w_.pixelPmf) {
    const ParameterSlot* slot = params_.pixelLogits(w_.view);
    if (!slot || w_.pixelCell < 0) return;
    addSoftmaxLogPmfAdjoint(std::span<const float>(w_.pixelPmf, n), s_.selection, out);
    for (size_t k = 0; k < n; ++k) grad_.add(uint32_t(slot->offset + uint32_t(w_.pixelCell) * uint32_t(n) + uint32_t(k)), float(out[k]));
    return;
  }
  if (!scene_.selectsByPower()) {
    int off = params_.lightLogitsOffset();
    if (off < 0) return;
    thread_local std::vector<float> pmf;
    pmf.resize(n);
    for (size_t k = 0; k < n; ++k) pmf[k] = scene_.lightSelection().pmf(k);
    addSoftmaxLogPmfAdjoint(pmf, s_.selection, out);
    for (size_t k = 0; k < n; ++k) grad_.add(uint32_t(off + int(k)), float(out[k]));
    return;
  }
  // By power: every optimised intensity moves every light's probability.
  double sum = 0;
  for (double c : s_.selection) sum += c;
  for (size_t k = 0; k < n; ++k) {
    int off = params_.intensityOffset(int(k));
    if (off < 0) continue;
    Rgb g = powerLogPmfAdjoint(scene_.lights[k], scene_.radius, scene_.selectionPower(k), scene_.selectionPowerTotal(), s_.selection[k], sum);
    for (int c = 0; c < 3; ++c) grad_.add(uint32_t(off + c), g[c]);
  }
}

void VarianceVisitor::finish() {
  const Rgb F = L_;
  const bool detached = w_.detached;
  // dLoss/dF per channel through 2 (F - I1) dF, and the score's weight (F^2 - 2 I1 F), channel-summed.
  const Rgb wF = w_.adjoint * (F - w_.mean) * 2.f;
  const double u = detached ? 0.0 : dotRgb(w_.adjoint, F * F - w_.mean * F * 2.f);
  auto weighted = [&](Rgb x) { return dotRgb(wF, x); };

  // Continuation factors f/pdf of each bounce multiply what was gathered after it.
  for (Bounce& b : s_.bounces) {
    Rgb after = F - b.gathered;
    b.alpha = wF * after;
    b.gamma = detached ? 0.0 : -weighted(after) + u + weighted(b.misE);
  }
  if (!detached) {
    // Roulette: 1/q in beta after a survival, and the score of survival (log q) or termination
    // (log(1 - q) = -q/(1 - q) d log q). Last to first: throughput roulette pushes its
    // coefficient onto the bounces and earlier roulettes its q was made of.
    for (size_t i = s_.roulettes.size(); i-- > 0;) {
      Roulette& r = s_.roulettes[i];
      r.coef += r.survived ? -weighted(F - r.gathered) + u : -u * double(r.q) / (1.0 - double(r.q));
      // Fixed survival at q = 1 never terminates, yet E[F^2] = ... + M / q keeps a derivative there
      // (the parameter's bound; Adam needs the left derivative). The termination branch's
      // expectation, P(end) * score = (1 - q) * u_end * (-q / (1 - q)) = -q u_end, is finite: add it
      // outright, with u_end the score weight of the radiance gathered before the decision.
      if (r.q >= 1.f) r.coef -= dotRgb(w_.adjoint, r.gathered * r.gathered - w_.mean * r.gathered * 2.f);
      if (r.channel >= 0) {
        // q = max_c beta_c (before this division): d log q = sum of the earlier bounces' d log(f_c/pdf)
        // at that channel, minus the earlier roulettes' d log q.
        for (int k = 0; k < r.bouncesBefore; ++k) {
          Bounce& b = s_.bounces[size_t(k)];
          b.alpha[r.channel] += float(r.coef);  // on d f_c / f_c of that channel
          b.gamma -= r.coef;
        }
        for (size_t j = 0; j < i; ++j) s_.roulettes[j].coef -= r.coef;
      } else if (int off = params_.survivalOffset(); off >= 0 && r.coef != 0.0) {
        const size_t index = std::min(size_t(r.depth), scene_.sampling.survival.size() - 1);
        grad_.add(uint32_t(off + int(index)), float(r.coef / double(r.q)));
      }
    }
  }
  for (const Bounce& b : s_.bounces) {
    if (!hasBsdfParameters(params_, b.material)) continue;
    Rgb adj(b.f.x > 0.f ? b.alpha.x / b.f.x : 0.f, b.f.y > 0.f ? b.alpha.y / b.f.y : 0.f, b.f.z > 0.f ? b.alpha.z / b.f.z : 0.f);
    addBsdfGradient(params_, scene_, b.material, b.uv, b.dd, adj, grad_);
    addPdfGradient(b.material, b.uv, b.pdf, b.gamma);
  }
  for (const Nee& n : s_.nees) {
    if (hasBsdfParameters(params_, n.material)) {
      addBsdfGradient(params_, scene_, n.material, n.uv, n.dd, wF * n.Cf, grad_);
      // MIS: d log w = 2 (1 - w) (d log pmf_light - d log pdf_bsdf).
      if (!detached) addPdfGradient(n.material, n.uv, n.pdf, -double(n.misFactor) * weighted(n.C));
    }
    // 1/pmf in the contribution, and the light half of the MIS weight.
    if (!detached) s_.selection[n.light] += (double(n.misFactor) - 1.0) * weighted(n.C);
  }
  if (!detached) {
    for (const Rejected& r : s_.rejected) addPdfGradient(r.material, r.uv, r.pdf, u);
    for (size_t l = 0; l < s_.selection.size(); ++l) s_.selection[l] += u * s_.choices[l] + weighted(s_.selectionMis[l]);
    addSelectionGradient();
  }
  for (size_t l = 0; l < s_.perUnit.size(); ++l) {
    int off = params_.intensityOffset(int(l));
    if (off < 0 || isBlack(s_.perUnit[l])) continue;
    Rgb g = wF * s_.perUnit[l];
    for (int c = 0; c < 3; ++c) grad_.add(uint32_t(off + c), g[c]);
  }
}

Rgb walkVariancePath(const Scene& scene, const ParameterRegistry& params, Vec3 o, Vec3 d, Sampler& sampler, WalkSettings s,
                     const VarianceWeights& weights, PathContext* ctx, PathGradient& grad, const PrimaryHit* primary) {
  s.lightPmf = weights.pixelPmf;
  VarianceVisitor v(scene, params, weights, grad);
  auto direct = [&](const ShadingPoint& sp, int, Sampler& smp, PathContext* c, DirectPath& out) {
    int chosen = -1;
    bool ok = sampleDirectNee(scene, sp, smp, c, out, weights.pixelPmf, &chosen);
    v.lightChoice(chosen);
    return ok;
  };
  walkPath(scene, o, d, sampler, s, direct, v, ctx, primary);
  v.finish();
  return v.radiance();
}

}  // namespace invr
