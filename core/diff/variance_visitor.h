// The variance visitor of the shared walk (core/render/path_walk.h): one random walk's estimate F
// of its pixel and the derivative of that pixel's variance term (Yan et al. 2024, Eq. 10-25).
//
// The walk is one sample x of every random decision it makes: light index and light point at each
// NEE, a BSDF direction at each vertex (with its marginal, mixture density; directions drawn and
// then rejected included), each Russian-roulette survival and termination. With q(x) their joint
// density, E[F^2] = int F^2 q dx, so
//     d E[F^2] = E[ 2 F dF + F^2 S ],   S = sum over decisions of d log q(decision),
// where dF is the derivative at fixed decisions with every pdf, MIS weight and roulette
// probability inside F attached (Eq. 25 in expanded form). The variance V = E[F^2] - I^2 needs
// dI too, estimated from the same walk (dF + F S) and multiplied by an independent estimate I1
// of I (the primal render): with I1 independent of x (Eq. 18),
//     dV^ = 2 (F - I1) dF + (F^2 - 2 I1 F) S          per channel, S shared by the channels.
// `detached` gives the baseline of Weier et al. 2021 / Mitsuba's moment integrator under AD
// (Eq. 24): pdfs, MIS weights, light selection and roulette treated as constants and no score,
// dV^ = 2 (F - I1) dF_detached, biased wherever a parameter enters a density.
//
// Everything is linear in per-decision log-derivatives, so the walk keeps one small record per
// decision and finish() expands them once F is known (no second walk): continuation factors
// f/pdf/q of a bounce multiply what was gathered after it, as in path_adjoint.h; throughput
// roulette's q = max_c beta_c depends on every earlier bounce, so its coefficient is pushed back
// onto those records (processed last to first).
#pragma once

#include <vector>

#include "core/diff/bsdf_adjoint.h"
#include "core/lights/light_selection.h"
#include "core/render/path_walk.h"

namespace invr {

// Per camera sample: what its variance derivative is weighted by.
struct VarianceWeights {
  Rgb mean{0.f};     // I1: an independent unbiased estimate of the pixel's radiance
  Rgb adjoint{0.f};  // dLoss/dV of the pixel per channel, divided among the pixel's samples
  bool detached = false;
  int view = 0;
  const float* pixelPmf = nullptr;  // the sample's light-selection pmf when per-pixel logits apply
  int pixelCell = -1;               // ... and its cell in the view's logit map
};

class VarianceVisitor {
 public:
  VarianceVisitor(const Scene& scene, const ParameterRegistry& params, const VarianceWeights& w, PathGradient& grad)
      : scene_(scene), params_(params), w_(w), grad_(grad), s_(scratch()) {
    s_.clear(scene.lights.size());
  }

  // --- walk hooks ---
  void emission(Rgb weight, Rgb Le, const LightSampleRef& light, float perUnit, EmissionMis mis) {
    Rgb E = weight * Le;
    L_ += E;
    if (perUnit > 0.f) s_.perUnit[light.light] += weight * perUnit;
    // d log w_bsdf = 2 (1 - w) (d log pdf_bsdf - d log pmf_light): onto the bounce that found it.
    if (mis.weighted && !s_.bounces.empty() && mis.w < 1.f) {
      Bounce& b = s_.bounces.back();
      b.misE += E * (2.f * (1.f - mis.w));
      s_.selectionMis[light.light] -= E * (2.f * (1.f - mis.w));
    }
  }
  void emission(Rgb weight, Rgb Le, const LightSampleRef& light, float perUnit) { emission(weight, Le, light, perUnit, EmissionMis{}); }
  // Every NEE light choice (contributing or not): its score.
  void lightChoice(int light) {
    if (light >= 0) s_.choices[size_t(light)] += 1.0;
  }
  void direct(Rgb beta, const DirectPath& p, const WalkVertex& v) {
    Rgb C = beta * p.contribution();
    L_ += C;
    Nee n;
    n.material = v.material;
    n.uv = v.hit->uv;
    n.light = p.light.light;
    n.C = C;
    n.Cf = beta * p.weight * p.emission;  // dC/d(f|cos|) per channel
    if (p.throughBsdf && hasBsdfParameters(params_, v.material)) {
      n.dd = v.bsdf->evalDerivatives(v.wo, p.wiLocal);
      if (p.misWeighted) n.pdf = v.bsdf->sampledPdf(v.wo, p.wiLocal);
    }
    n.misFactor = p.misWeighted ? 2.f * (1.f - p.mis) : 0.f;
    if (p.emissionPerUnit > 0.f) s_.perUnit[p.light.light] += beta * p.weight * p.bsdfValue * p.emissionPerUnit;
    s_.nees.push_back(n);
  }
  void bounce(const WalkVertex& v, Vec3 wi) {
    Bounce b;
    b.material = v.material;
    b.uv = v.hit->uv;
    b.gathered = L_;
    if (hasBsdfParameters(params_, v.material)) {
      b.dd = v.bsdf->evalDerivatives(v.wo, wi);
      b.f = v.bsdf->eval(v.wo, wi);
      b.pdf = v.bsdf->sampledPdf(v.wo, wi);
    }
    s_.bounces.push_back(b);
  }
  void rejected(const WalkVertex& v, float uc, Vec2 u) {
    if (!hasBsdfParameters(params_, v.material)) return;
    Rejected r{v.material, v.hit->uv, v.bsdf->sampledPdf(v.wo, v.bsdf->sampledDirection(v.wo, uc, u))};
    s_.rejected.push_back(r);
  }
  void roulette(float q, bool survived, int channel, int depth) {
    s_.roulettes.push_back(Roulette{q, survived, channel, int(s_.bounces.size()), depth, L_, 0.0});
  }

  Rgb radiance() const { return L_; }
  // Adds the sample's weighted variance derivative to the path gradient; call once, after the walk.
  void finish();

 private:
  struct Bounce {
    int material = -1;
    Vec2 uv;
    BsdfDerivatives dd;
    Rgb f{0.f};
    PdfDerivatives pdf;
    Rgb gathered{0.f};
    Rgb misE{0.f};      // 2 (1 - w) * emission found through this bounce, MIS-weighted
    Rgb alpha{0.f};     // finish(): coefficient on d f_c / f_c
    double gamma = 0;   // finish(): coefficient on d log pdf
  };
  struct Nee {
    int material = -1;
    Vec2 uv;
    uint32_t light = 0;
    Rgb C{0.f}, Cf{0.f};
    BsdfDerivatives dd;
    PdfDerivatives pdf;
    float misFactor = 0.f;  // 2 (1 - w) when MIS-weighted
  };
  struct Rejected {
    int material;
    Vec2 uv;
    PdfDerivatives pdf;
  };
  struct Roulette {
    float q;
    bool survived;
    int channel;       // throughput roulette: the max channel of beta; -1: fixed survival
    int bouncesBefore;  // bounce records whose factors beta held
    int depth;          // the vertex whose bounce it followed (fixed survival: its index)
    Rgb gathered;
    double coef;        // finish(): coefficient on d log q
  };
  struct Scratch {
    std::vector<Bounce> bounces;
    std::vector<Nee> nees;
    std::vector<Rejected> rejected;
    std::vector<Roulette> roulettes;
    std::vector<double> choices;      // NEE choices per light (score)
    std::vector<Rgb> selectionMis;    // per light: coefficient (per channel of F) on d log pmf from MIS
    std::vector<Rgb> perUnit;         // per light: d F / d (light value), per channel
    std::vector<double> selection;    // finish(): per light, coefficient on d log pmf
    void clear(size_t lights) {
      bounces.clear();
      nees.clear();
      rejected.clear();
      roulettes.clear();
      choices.assign(lights, 0.0);
      selectionMis.assign(lights, Rgb(0.f));
      perUnit.assign(lights, Rgb(0.f));
      selection.assign(lights, 0.0);
    }
  };
  // One per thread, reused: a walk allocates nothing once the vectors have grown.
  static Scratch& scratch() {
    thread_local Scratch s;
    return s;
  }
  void addPdfGradient(int material, Vec2 uv, const PdfDerivatives& pdf, double coefLog);
  void addSelectionGradient();

  const Scene& scene_;
  const ParameterRegistry& params_;
  const VarianceWeights& w_;
  PathGradient& grad_;
  Scratch& s_;
  Rgb L_{0.f};
};

// One camera path of the variance pass: its radiance, with the weighted variance derivative added
// to `grad`. `direct` is NEE + MIS (the only strategy with variance derivatives). `primary`: the
// camera ray's hit when traced beforehand (walkPath).
Rgb walkVariancePath(const Scene& scene, const ParameterRegistry& params, Vec3 o, Vec3 d, Sampler& sampler, WalkSettings s,
                     const VarianceWeights& weights, PathContext* ctx, PathGradient& grad, const PrimaryHit* primary = nullptr);

}  // namespace invr
