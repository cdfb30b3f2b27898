#include "bake/generator_training.h"

#include <dlfcn.h>
#include <torch/torch.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numbers>
#include <random>

#include "core/error.h"
#include "core/file_util.h"
#include "core/hash.h"
#include "core/metrics.h"
#include "core/octahedral.h"
#include "core/progress.h"
#include "core/sh.h"
#include "worlds/probe_placement.h"

namespace lfgi::bake {

namespace {

constexpr int kBase = 4;

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// libtorch's intra-op pool is OpenMP; the BLAS behind it (Debian: OpenBLAS, pthread build) keeps its own
// pool, set through its C entry point when the loaded BLAS has one.
void setThreads(int threads) {
  torch::set_num_threads(threads);
  using SetFn = void (*)(int);
  for (const char* name : {"openblas_set_num_threads", "goto_set_num_threads"}) {
    if (void* f = dlsym(RTLD_DEFAULT, name)) {
      SetFn fn;
      std::memcpy(&fn, &f, sizeof fn);
      fn(threads);
      break;
    }
  }
}

// ---- the network (core/generator.h) ----------------------------------------------------------------
struct GeneratorNetImpl : torch::nn::Module {
  explicit GeneratorNetImpl(const GeneratorArch& a) : c0(a.convChannels.front()) {
    linear = register_module("linear", torch::nn::Linear(a.inputDim(), kBase * kBase * c0));
    for (int i = 0; i < a.layers(); ++i)
      convs.push_back(register_module(
          "conv" + std::to_string(i),
          torch::nn::ConvTranspose2d(torch::nn::ConvTranspose2dOptions(a.convChannels[size_t(i)],
                                                                       a.convChannels[size_t(i) + 1],
                                                                       kGeneratorKernel)
                                         .stride(2)
                                         .padding(1))));
  }
  // film: a per-cell adapter (core/generator.h GeneratorAdapter) as [2][channels] (scale row, shift row),
  // undefined for none; `stages` of it are applied.
  torch::Tensor forward(const torch::Tensor& x, const torch::Tensor& film = {}, int stages = 0) {
    auto modulate = [&](torch::Tensor h, int stage, int64_t& base) {
      if (stage >= stages) return h;
      const int64_t c = h.size(1);
      std::vector<int64_t> shape(size_t(h.dim()), 1);
      shape[1] = c;
      torch::Tensor g = film[0].narrow(0, base, c).view(shape), b = film[1].narrow(0, base, c).view(shape);
      base += c;
      return h * (g + 1.0) + b;
    };
    int64_t base = 0;
    torch::Tensor h = linear->forward(x);
    if (stages > 0) h = modulate(h.view({-1, c0, kBase * kBase}), 0, base);
    h = torch::relu(h).view({-1, c0, kBase, kBase});
    for (size_t i = 0; i < convs.size(); ++i) {
      h = modulate(convs[i]->forward(h), int(i) + 1, base);
      if (i + 1 < convs.size()) h = torch::relu(h);
    }
    return h;
  }
  int c0;
  torch::nn::Linear linear{nullptr};
  std::vector<torch::nn::ConvTranspose2d> convs;
};
TORCH_MODULE(GeneratorNet);

// Conditional DCGAN discriminator (Radford et al. 2015: strided convs, LeakyReLU 0.2, no pooling).
struct DiscriminatorImpl : torch::nn::Module {
  DiscriminatorImpl(int resolution, int width, int condDim) {
    int c = kGeneratorChannels, w = width;
    for (int res = resolution, i = 0; res > kBase; res /= 2, ++i) {
      convs.push_back(register_module(
          "conv" + std::to_string(i),
          torch::nn::Conv2d(torch::nn::Conv2dOptions(c, w, kGeneratorKernel).stride(2).padding(1))));
      c = w;
      w *= 2;
    }
    head = register_module("head", torch::nn::Linear(c * kBase * kBase + condDim, 1));
  }
  torch::Tensor forward(torch::Tensor x, const torch::Tensor& cond) {
    for (auto& conv : convs) x = torch::leaky_relu(conv->forward(x), 0.2);
    x = x.flatten(1);
    if (cond.defined() && cond.size(1) > 0) x = torch::cat({x, cond}, 1);
    return head->forward(x);
  }
  std::vector<torch::nn::Conv2d> convs;
  torch::nn::Linear head{nullptr};
};
TORCH_MODULE(Discriminator);

torch::Tensor fromVector(const std::vector<float>& v, std::vector<int64_t> shape) {
  return torch::from_blob(const_cast<float*>(v.data()), shape, torch::kFloat32).clone();
}

std::vector<float> toVector(const torch::Tensor& t) {
  torch::Tensor c = t.detach().contiguous().to(torch::kFloat32);
  return std::vector<float>(c.data_ptr<float>(), c.data_ptr<float>() + c.numel());
}

GeneratorWeights exportWeights(GeneratorNet& net, const GeneratorArch& arch) {
  GeneratorWeights w;
  w.arch = arch;
  w.linearWeight = toVector(net->linear->weight);
  w.linearBias = toVector(net->linear->bias);
  for (auto& conv : net->convs) {
    w.convWeight.push_back(toVector(conv->weight));
    w.convBias.push_back(toVector(conv->bias));
  }
  return w;
}

void importWeights(GeneratorNet& net, const GeneratorWeights& w) {
  torch::NoGradGuard noGrad;
  const int64_t c0 = w.arch.convChannels.front();
  net->linear->weight.copy_(fromVector(w.linearWeight, {kBase * kBase * c0, w.arch.inputDim()}));
  net->linear->bias.copy_(fromVector(w.linearBias, {kBase * kBase * c0}));
  for (size_t i = 0; i < net->convs.size(); ++i) {
    const int64_t ci = w.arch.convChannels[i], co = w.arch.convChannels[i + 1];
    net->convs[i]->weight.copy_(fromVector(w.convWeight[i], {ci, co, kGeneratorKernel, kGeneratorKernel}));
    net->convs[i]->bias.copy_(fromVector(w.convBias[i], {co}));
  }
}

// ---- irradiance operator (the metric) ------------------------------------------------------------
// K[t][q] = max(0, normal_q . w_t) Omega_t: radiance texel t of an n x n map to irradiance texel q of
// an m x m map (texel-centre normals).
std::vector<double> irradianceKernel(int n, int m) {
  const std::vector<double> omega = octTexelSolidAngles(n);
  std::vector<glm::vec3> dirs(size_t(n * n)), normals(size_t(m * m));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) dirs[size_t(j * n + i)] = octTexelDirection(i, j, n);
  for (int j = 0; j < m; ++j)
    for (int i = 0; i < m; ++i) normals[size_t(j * m + i)] = octTexelDirection(i, j, m);
  std::vector<double> k(size_t(n * n) * size_t(m * m));
  for (size_t t = 0; t < dirs.size(); ++t)
    for (size_t q = 0; q < normals.size(); ++q)
      k[t * normals.size() + q] = std::max(0.0, double(glm::dot(normals[q], dirs[t]))) * omega[t];
  return k;
}

// ---- data tensors ---------------------------------------------------------------------------------
struct Data {
  int n = 0, m = 0;
  int64_t P = 0, K = 0, S = 0;  // probes, keys, samples (s = k * P + p)
  GeneratorOutputScale scale;
  torch::Tensor target;           // [S][11][n][n] encoded
  torch::Tensor irradiance;       // [S][3][m*m] of the captured radiance
  torch::Tensor irradianceDen;    // [S]: the per-sample irradiance loss's denominator (generator_training.h)
  torch::Tensor kernel;           // [n*n][m*m]
  torch::Tensor radianceWeight;   // [n][n], solid angle normalised to mean 1
  torch::Tensor cond;             // [K][condDim]
  torch::Tensor positionLatents;  // [P][L] (PositionFourier)
};

float autoExposure(const GeneratorTrainingSet& set) {
  double sum = 0.0;
  size_t count = 0;
  for (const LightingKey& k : set.keys)
    for (const ProbeCapture& c : k.probes) {
      for (float v : c.radiance) sum += v;
      count += c.radiance.size();
    }
  return float(std::max(0.1 * sum / double(std::max<size_t>(count, 1)), 1e-8));
}

float autoRange(const GeneratorTrainingSet& set) {
  std::vector<float> r;
  for (const LightingKey& k : set.keys)
    for (const ProbeCapture& c : k.probes)
      for (size_t t = 0; t < c.distance.size(); t += 2) r.push_back(c.distance[t]);
  if (r.empty()) return 1.0f;
  const size_t q = std::min(r.size() - 1, size_t(0.95 * double(r.size())));
  std::nth_element(r.begin(), r.begin() + ptrdiff_t(q), r.end());
  return std::max(1.5f * r[q], 1.0f);
}

Data makeData(const GeneratorTrainingSet& set, const GeneratorTrainingOptions& o) {
  Data d;
  d.n = set.resolution();
  d.m = set.irradianceResolution();
  d.P = int64_t(set.probeCount());
  d.K = int64_t(set.keys.size());
  d.S = d.P * d.K;
  d.scale.exposure = o.exposure > 0.0f ? o.exposure : autoExposure(set);
  d.scale.range = o.range > 0.0f ? o.range : autoRange(set);
  const int64_t T = int64_t(d.n) * d.n, M = int64_t(d.m) * d.m;
  std::vector<float> target(size_t(d.S * kGeneratorChannels * T));
  std::vector<float> radiance(size_t(d.S * 3 * T));
  const double e = d.scale.exposure, range = d.scale.range;
  for (int64_t k = 0; k < d.K; ++k)
    for (int64_t p = 0; p < d.P; ++p) {
      const ProbeCapture& c = set.keys[size_t(k)].probes[size_t(p)];
      float* y = &target[size_t((k * d.P + p) * kGeneratorChannels * T)];
      float* l = &radiance[size_t((k * d.P + p) * 3 * T)];
      for (int64_t t = 0; t < T; ++t) {
        for (int ch = 0; ch < 3; ++ch) {
          const double L = std::max(0.0f, c.radiance[size_t(t * 3 + ch)]);
          y[ch * T + t] = float(std::log1p(L / e));
          l[ch * T + t] = float(L);
          y[(5 + ch) * T + t] = c.normal[size_t(t * 3 + ch)];
          y[(8 + ch) * T + t] = c.albedo[size_t(t * 3 + ch)];
        }
        y[3 * T + t] = float(std::clamp(c.distance[size_t(t * 2)] / range, 0.0, 1.0));
        y[4 * T + t] = float(std::clamp(c.distance[size_t(t * 2 + 1)] / (range * range), 0.0, 1.0));
      }
    }
  d.target = fromVector(target, {d.S, kGeneratorChannels, d.n, d.n});
  const std::vector<double> k = irradianceKernel(d.n, d.m);
  d.kernel = torch::from_blob(const_cast<double*>(k.data()), {T, M}, torch::kFloat64).to(torch::kFloat32);
  d.irradiance = torch::matmul(fromVector(radiance, {d.S, 3, T}), d.kernel);
  // Per key (a night key is held to its own light, not the day's): |E_s|^2 + f^2 mean over the key's probes.
  const torch::Tensor e2 = d.irradiance.pow(2).sum({1, 2}).reshape({d.K, d.P});
  const double floor = double(o.loss.irradianceFloor);
  d.irradianceDen = (e2 + floor * floor * e2.mean(1, true)).reshape({d.S}).clamp_min(1e-30);
  const std::vector<double> omega = octTexelSolidAngles(d.n);
  std::vector<float> w(omega.size());
  for (size_t t = 0; t < w.size(); ++t) w[t] = float(omega[t] * double(T) / (4.0 * std::numbers::pi));
  d.radianceWeight = fromVector(w, {d.n, d.n});
  std::vector<float> cond;
  for (const LightingKey& key : set.keys) {
    const auto c = conditioningVector(key.timeOfDayHours, key.weather);
    if (o.arch.condDim > 0) cond.insert(cond.end(), c.begin(), c.end());
  }
  d.cond = o.arch.condDim > 0 ? fromVector(cond, {d.K, o.arch.condDim}) : torch::zeros({d.K, 0});
  if (o.arch.latentSource == LatentSource::PositionFourier) {
    std::vector<float> z(size_t(d.P * o.arch.latentDim));
    for (int64_t p = 0; p < d.P; ++p)
      positionLatent(set.positions01[size_t(p)], o.arch.fourierOctaves,
                     std::span<float>(z).subspan(size_t(p * o.arch.latentDim), size_t(o.arch.latentDim)));
    d.positionLatents = fromVector(z, {d.P, o.arch.latentDim});
  }
  return d;
}

uint64_t fingerprint(const GeneratorTrainingSet& set, const GeneratorTrainingOptions& o, const Data& d) {
  uint64_t h = fnv1aValue(kFnv1aOffset, set.contentHash());
  const GeneratorArch& a = o.arch;
  h = fnv1aValue(h, a.latentDim);
  h = fnv1aValue(h, a.condDim);
  for (int c : a.convChannels) h = fnv1aValue(h, c);
  h = fnv1aValue(h, uint8_t(a.latentSource));
  h = fnv1aValue(h, a.fourierOctaves);
  for (float v : {o.learningRate, o.latentLearningRate, o.loss.radiance, o.loss.irradiance, o.loss.distance,
                  o.loss.normal, o.loss.albedo, o.loss.latent, o.loss.adversarial, o.loss.irradianceFloor,
                  d.scale.exposure, d.scale.range})
    h = fnv1aValue(h, v);
  for (int v : {o.maxSteps, o.discriminatorWidth, o.batchSize, int(o.adversarial), o.latentQuantBits})
    h = fnv1aValue(h, v);
  return fnv1aValue(h, o.seed);
}

// Sample indices of step t: positions t*B .. t*B+B-1 of an endless sequence of per-epoch permutations
// (epoch e shuffled by mt19937_64(seed, e)), so a step's batch depends only on (seed, t).
class BatchSchedule {
 public:
  BatchSchedule(int64_t samples, int batchSize, uint64_t seed) : S_(samples), B_(batchSize), seed_(seed) {}
  torch::Tensor batch(int64_t step) {
    if (B_ >= S_) return torch::arange(S_, torch::kLong);
    std::vector<int64_t> idx(static_cast<size_t>(B_));
    for (int64_t i = 0; i < B_; ++i) {
      const int64_t q = step * B_ + i;
      const int64_t epoch = q / S_;
      if (epoch != epoch_) {
        perm_.resize(size_t(S_));
        for (int64_t s = 0; s < S_; ++s) perm_[size_t(s)] = s;
        std::seed_seq seq{uint32_t(seed_), uint32_t(seed_ >> 32), uint32_t(epoch), uint32_t(epoch >> 32)};
        std::mt19937_64 rng(seq);
        std::shuffle(perm_.begin(), perm_.end(), rng);
        epoch_ = epoch;
      }
      idx[size_t(i)] = perm_[size_t(q % S_)];
    }
    return torch::from_blob(idx.data(), {B_}, torch::kLong).clone();
  }

 private:
  int64_t S_, B_;
  uint64_t seed_;
  int64_t epoch_ = -1;
  std::vector<int64_t> perm_;
};

float learningRateAt(const GeneratorTrainingOptions& o, int step) {
  float lr = o.learningRate;
  if (step >= int(0.6 * o.maxSteps)) lr *= 0.5f;
  if (step >= int(0.85 * o.maxSteps)) lr *= 0.5f;
  return lr;
}

void setGroupLr(torch::optim::Adam& opt, size_t group, float lr) {
  static_cast<torch::optim::AdamOptions&>(opt.param_groups()[group].options()).lr(lr);
}

// Straight-through fake quantization (Bengio et al. 2013; Jacob et al. 2018): the forward pass sees x
// on the symmetric `bits` grid of core/quantize.h with one scale per column (x: [rows][columns], scale =
// max over the column |x| / M), the backward pass the identity. bits 0: x unchanged. The grid is exactly
// quantizePerChannel's (same float division, round half to even), so exported grid values quantize back
// to themselves.
torch::Tensor fakeQuantize(const torch::Tensor& x, int bits) {
  if (bits <= 0) return x;
  const double m = double((1 << (bits - 1)) - 1);
  torch::Tensor s = (x.detach().abs().amax(0, true) / m);
  torch::Tensor safe = torch::where(s > 0, s, torch::ones_like(s));
  torch::Tensor q = torch::where(s > 0, (x.detach() / safe).round().clamp(-m, m) * s, torch::zeros_like(x));
  return x + (q - x.detach());
}

// Radiance channels of raw outputs y [B][11][n][n] through the metric's irradiance operator: [B][3][m*m].
torch::Tensor predictedIrradiance(const torch::Tensor& y, const Data& d) {
  const int64_t T = int64_t(d.n) * d.n;
  torch::Tensor L = torch::expm1(y.narrow(1, 0, 3).clamp(0.0, 20.0)) * d.scale.exposure;
  return torch::matmul(L.reshape({y.size(0), 3, T}), d.kernel);
}

// The reconstruction part of the loss (file comment of generator_training.h) of outputs y for samples idx.
torch::Tensor reconstructionLoss(const torch::Tensor& y, const torch::Tensor& idx, const Data& d,
                                 const TrainingLossWeights& w) {
  torch::Tensor ref = d.target.index_select(0, idx);
  torch::Tensor diff2 = (y - ref).pow(2);
  torch::Tensor total = w.radiance * (diff2.narrow(1, 0, 3) * d.radianceWeight).mean() +
                        w.distance * diff2.narrow(1, 3, 2).mean() + w.normal * diff2.narrow(1, 5, 3).mean() +
                        w.albedo * diff2.narrow(1, 8, 3).mean();
  if (w.irradiance > 0.0f) {
    torch::Tensor err2 = (predictedIrradiance(y, d) - d.irradiance.index_select(0, idx)).pow(2).sum({1, 2});
    total = total + w.irradiance * (err2 / d.irradianceDen.index_select(0, idx)).mean();
  }
  return total;
}

// Irradiance relative RMS over every sample of d, outputs from forward(idx) (libtorch; exported models
// are re-measured with the core decoder).
template <typename Forward>
double irradianceError(const Data& d, Forward&& forward) {
  torch::NoGradGuard noGrad;
  double num = 0.0, den = 0.0;
  for (int64_t s0 = 0; s0 < d.S; s0 += 1024) {
    torch::Tensor idx = torch::arange(s0, std::min(d.S, s0 + 1024), torch::kLong);
    torch::Tensor e = predictedIrradiance(forward(idx), d), ref = d.irradiance.index_select(0, idx);
    num += (e - ref).pow(2).sum().item<double>();
    den += ref.pow(2).sum().item<double>();
  }
  return den > 0.0 ? std::sqrt(num / den) : (num > 0.0 ? INFINITY : 0.0);
}

// Checkpoints (atomic; meta = [fingerprint, step, bits of the last step's loss]). openCheckpoint: the
// step of the checkpoint at path (and its loss), nullopt if there is none; throws if it is unreadable or
// of other data or options.
std::optional<int> openCheckpoint(const std::filesystem::path& path, uint64_t fp,
                                  torch::serialize::InputArchive& ar, double* loss = nullptr) {
  if (path.empty() || !std::filesystem::exists(path)) return std::nullopt;
  try {
    ar.load_from(path.string());
  } catch (const std::exception& e) {
    fail("{}: not a readable training checkpoint ({})", path.string(), e.what());
  }
  torch::Tensor meta;
  ar.read("meta", meta);
  if (meta.numel() != 3 || uint64_t(meta[0].item<int64_t>()) != fp)
    fail("{}: checkpoint of other training data or options (delete it to start over)", path.string());
  if (loss) *loss = std::bit_cast<double>(meta[2].item<int64_t>());
  return int(meta[1].item<int64_t>());
}

void saveCheckpointArchive(const std::filesystem::path& path, uint64_t fp, int step, double loss,
                           torch::serialize::OutputArchive& ar) {
  ar.write("meta",
           torch::tensor(std::vector<int64_t>{int64_t(fp), int64_t(step), std::bit_cast<int64_t>(loss)},
                         torch::kLong));
  writeViaTempFile(path, [&](const std::filesystem::path& tmp) { ar.save_to(tmp.string()); });
}

// After the training loop: an interrupted run writes its checkpoint, and so does a finished one the caller
// keeps (GeneratorTrainingOptions::keepFinishedCheckpoint); any other finished one removes it (nothing is
// left to resume; its result goes to the caller, the cell file).
template <typename Save>
void closeCheckpoint(bool interrupted, bool keepFinished, const std::filesystem::path& path, Save&& save) {
  if (interrupted || (keepFinished && !path.empty())) {
    save();
  } else if (!path.empty()) {
    std::error_code ec;
    std::filesystem::remove(path, ec);
  }
}

// The bookkeeping after each optimiser step, shared by both training loops: counts the step, every
// evalEvery steps (and at the last) evaluates — false when the error is not finite (the caller restores
// the last finite state and stops) — else keeps the finite state (keep()), reports, and sets `done` at
// the target; then checkpoints (unless done) and moves the progress bar.
struct StepState {
  int& step;
  int& stepsThisCall;
  double& err;
  bool& done;
};
template <typename Eval, typename Keep, typename Save>
bool afterStep(const GeneratorTrainingOptions& o, const char* label, double loss, StepState st,
               Eval&& evaluate, Keep&& keep, Save&& save, std::optional<Progress>& progress) {
  ++st.step;
  ++st.stepsThisCall;
  if (st.step % o.evalEvery == 0 || st.step == o.maxSteps) {
    st.err = evaluate();
    if (!std::isfinite(st.err)) return false;
    keep();
    if (o.showProgress)
      std::fprintf(stderr, "\n%s: step %d loss %.5f irradiance rel RMS %.4f (target %.4f)\n", label, st.step,
                   loss, st.err, o.irradianceErrorTarget);
    if (st.err <= o.irradianceErrorTarget) st.done = true;
  }
  if (!o.checkpoint.empty() && st.step % o.checkpointEvery == 0 && !st.done) save();
  if (progress) progress->update(size_t(st.step));
  return true;
}

std::vector<torch::Tensor> snapshotOf(const std::vector<torch::Tensor>& tensors) {
  std::vector<torch::Tensor> st;
  for (const torch::Tensor& t : tensors) st.push_back(t.detach().clone());
  return st;
}

void restoreFrom(const std::vector<torch::Tensor>& tensors, const std::vector<torch::Tensor>& snapshot) {
  torch::NoGradGuard noGrad;
  for (size_t i = 0; i < tensors.size(); ++i) tensors[i].copy_(snapshot[i]);
}

}  // namespace

// ---- training set ----------------------------------------------------------------------------------
int GeneratorTrainingSet::resolution() const {
  return keys.empty() || keys[0].probes.empty() ? 0 : keys[0].probes[0].resolution;
}
int GeneratorTrainingSet::irradianceResolution() const {
  return keys.empty() || keys[0].probes.empty() ? 0 : keys[0].probes[0].irradianceResolution;
}

void GeneratorTrainingSet::validate() const {
  if (keys.empty()) fail("GeneratorTrainingSet: no lighting keys");
  if (positions01.empty()) fail("GeneratorTrainingSet: no probes");
  const int n = resolution(), m = irradianceResolution();
  for (size_t k = 0; k < keys.size(); ++k) {
    if (keys[k].probes.size() != positions01.size())
      fail("GeneratorTrainingSet.keys[{}] holds {} captures for {} probes", k, keys[k].probes.size(),
           positions01.size());
    for (size_t p = 0; p < keys[k].probes.size(); ++p) {
      const ProbeCapture& c = keys[k].probes[p];
      const size_t T = size_t(n) * size_t(n);
      if (c.resolution != n || c.irradianceResolution != m || c.radiance.size() != T * 3 ||
          c.distance.size() != T * 2 || c.normal.size() != T * 3 || c.albedo.size() != T * 3)
        fail("GeneratorTrainingSet.keys[{}].probes[{}]: maps missing or not {} x {} (irradiance {} x {})", k,
             p, n, n, m, m);
    }
  }
  if (n < 8) fail("GeneratorTrainingSet: resolution {} below the generator's smallest output (8)", n);
}

uint64_t GeneratorTrainingSet::contentHash() const {
  uint64_t h = kFnv1aOffset;
  for (glm::vec3 p : positions01) h = fnv1aValue(h, p);
  for (const LightingKey& k : keys) {
    h = fnv1aValue(h, k.timeOfDayHours);
    h = fnv1aValue(h, k.weather);
    for (const ProbeCapture& c : k.probes) h = fnv1aValue(h, c.contentHash());
  }
  return h;
}

std::vector<float> TrainedGenerator::decoderLatents(const GeneratorTrainingSet& set) const {
  const GeneratorArch& a = weights.arch;
  if (a.latentSource == LatentSource::Stored) return latents;
  std::vector<float> z(set.probeCount() * size_t(a.latentDim));
  for (size_t p = 0; p < set.probeCount(); ++p)
    positionLatent(set.positions01[p], a.fourierOctaves,
                   std::span<float>(z).subspan(p * size_t(a.latentDim), size_t(a.latentDim)));
  return z;
}

void GeneratorTrainingOptions::validate() const {
  arch.validate();
  if (maxSteps < 1) fail("GeneratorTrainingOptions.maxSteps = {}: need >= 1", maxSteps);
  if (!(irradianceErrorTarget >= 0.0)) fail("GeneratorTrainingOptions.irradianceErrorTarget must be >= 0");
  if (evalEvery < 1) fail("GeneratorTrainingOptions.evalEvery = {}: need >= 1", evalEvery);
  if (!(learningRate > 0.0f) || !(latentLearningRate > 0.0f))
    fail("GeneratorTrainingOptions: learning rates must be > 0");
  if (batchSize < 1) fail("GeneratorTrainingOptions.batchSize = {}: need >= 1", batchSize);
  if (threads < 1 || threads > 256) fail("GeneratorTrainingOptions.threads = {} outside [1, 256]", threads);
  if (discriminatorWidth < 1)
    fail("GeneratorTrainingOptions.discriminatorWidth = {}: need >= 1", discriminatorWidth);
  if (!(exposure >= 0.0f) || !(range >= 0.0f))
    fail("GeneratorTrainingOptions: exposure and range must be >= 0");
  if (!(loss.irradianceFloor >= 0.0f) || !std::isfinite(loss.irradianceFloor))
    fail("GeneratorTrainingOptions.loss.irradianceFloor = {}: need a finite value >= 0",
         loss.irradianceFloor);
  if (checkpointEvery < 1) fail("GeneratorTrainingOptions.checkpointEvery = {}: need >= 1", checkpointEvery);
  if (latentQuantBits != 0 && latentQuantBits != 4 && latentQuantBits != 8)
    fail("GeneratorTrainingOptions.latentQuantBits = {}: 0 (off), 4 or 8", latentQuantBits);
  if (arch.outChannels() != kGeneratorChannels)
    fail("GeneratorTrainingOptions.arch: {} output channels, the codec needs {}", arch.outChannels(),
         kGeneratorChannels);
}

GeneratorTrainingSet captureTrainingSet(const EmbreeScene& scene, std::span<const glm::vec3> positions,
                                        glm::vec3 boxMin, glm::vec3 boxMax,
                                        std::span<const LightingKeySpec> keys, const CaptureOptions& capture,
                                        const worlds::SkyState& sky, bool showProgress) {
  GeneratorTrainingSet set;
  for (glm::vec3 p : positions) {
    glm::vec3 q;
    for (int a = 0; a < 3; ++a) {
      const float ext = boxMax[a] - boxMin[a];
      q[a] = ext > 0.0f ? std::clamp((p[a] - boxMin[a]) / ext, 0.0f, 1.0f) : 0.5f;
    }
    set.positions01.push_back(q);
  }
  CaptureOptions co = capture;
  co.primaryDiscs = false;  // the codec carries what shading reads (header)
  for (const LightingKeySpec& k : keys) {
    worlds::SkyState s = sky;
    s.timeOfDayHours = k.timeOfDayHours;
    s.overcast = k.weather;
    CaptureResult r = captureProbes(scene, worlds::makeSky(s), positions, co, showProgress);
    if (r.probesDone != positions.size())
      fail("captureTrainingSet: capture interrupted after {} of {} probes", r.probesDone, positions.size());
    set.keys.push_back(LightingKey{k.timeOfDayHours, k.weather, std::move(r.probes)});
  }
  return set;
}

// ---- training --------------------------------------------------------------------------------------
namespace {

// trainGenerator's model and optimisers; latents are trained only when stored (else the position latents).
struct GeneratorModel {
  GeneratorNet& gen;
  torch::Tensor& latents;
  torch::optim::Adam& opt;
  Discriminator& disc;
  torch::optim::Adam& discOpt;
};

void checkGeneratorInputs(const GeneratorTrainingSet& set, const GeneratorTrainingOptions& o) {
  set.validate();
  o.validate();
  if (o.arch.outputResolution() != set.resolution())
    fail("GeneratorTrainingOptions.arch: output {} x {} but the captures are {} x {}",
         o.arch.outputResolution(), o.arch.outputResolution(), set.resolution(), set.resolution());
}

void loadGeneratorCheckpoint(torch::serialize::InputArchive& ar, const GeneratorTrainingOptions& o,
                             GeneratorModel m, bool stored) {
  torch::serialize::InputArchive g, og;
  ar.read("gen", g);
  m.gen->load(g);
  if (stored) {
    torch::NoGradGuard noGrad;
    torch::Tensor z;
    ar.read("latents", z);
    m.latents.copy_(z);
  }
  ar.read("opt", og);
  m.opt.load(og);
  if (o.adversarial) {
    torch::serialize::InputArchive dg, dog;
    ar.read("disc", dg);
    m.disc->load(dg);
    ar.read("discOpt", dog);
    m.discOpt.load(dog);
  }
}

void saveGeneratorCheckpoint(const GeneratorTrainingOptions& o, GeneratorModel m, bool stored, uint64_t fp,
                             int step, double loss) {
  if (o.checkpoint.empty()) return;
  torch::serialize::OutputArchive out, g, og;
  m.gen->save(g);
  out.write("gen", g);
  if (stored) out.write("latents", m.latents.detach());
  m.opt.save(og);
  out.write("opt", og);
  if (o.adversarial) {
    torch::serialize::OutputArchive dg, dog;
    m.disc->save(dg);
    out.write("disc", dg);
    m.discOpt.save(dog);
    out.write("discOpt", dog);
  }
  saveCheckpointArchive(o.checkpoint, fp, step, loss, out);
}

// Discriminator step on real captures vs the current (detached) outputs, then the generator's
// non-saturating term (Goodfellow et al. 2014), unweighted.
torch::Tensor adversarialTerm(Discriminator& disc, torch::optim::Adam& discOpt, const torch::Tensor& ref,
                              const torch::Tensor& y, const torch::Tensor& cond) {
  discOpt.zero_grad();
  torch::Tensor real = disc->forward(ref, cond), fake = disc->forward(y.detach(), cond);
  torch::Tensor dLoss = torch::binary_cross_entropy_with_logits(real, torch::ones_like(real)) +
                        torch::binary_cross_entropy_with_logits(fake, torch::zeros_like(fake));
  dLoss.backward();
  discOpt.step();
  torch::Tensor g = disc->forward(y, cond);
  return torch::binary_cross_entropy_with_logits(g, torch::ones_like(g));
}

// The exported model's errors through the core decoder, and whether they meet the target.
void reportCodecError(GeneratorTrainingReport& r, const CodecError& ce, const GeneratorTrainingOptions& o) {
  r.irradianceRelativeRms = ce.irradianceRelativeRms;
  r.radianceRelativeRms = ce.radianceRelativeRms;
  r.radiancePsnrDb = ce.radiancePsnrDb;
  r.reachedTarget = ce.irradianceRelativeRms <= o.irradianceErrorTarget;
}

}  // namespace

TrainedGenerator trainGenerator(const GeneratorTrainingSet& set, const GeneratorTrainingOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  checkGeneratorInputs(set, o);
  setThreads(o.threads);
  torch::manual_seed(o.seed);
  const Data d = makeData(set, o);
  const bool stored = o.arch.latentSource == LatentSource::Stored;

  GeneratorNet gen(o.arch);
  torch::Tensor latents =
      stored ? (torch::randn({d.P, o.arch.latentDim}) * 0.1).requires_grad_(true) : d.positionLatents;
  std::vector<torch::optim::OptimizerParamGroup> groups;
  groups.emplace_back(gen->parameters(), std::make_unique<torch::optim::AdamOptions>(o.learningRate));
  if (stored)
    groups.emplace_back(std::vector<torch::Tensor>{latents},
                        std::make_unique<torch::optim::AdamOptions>(o.latentLearningRate));
  torch::optim::Adam opt(std::move(groups), torch::optim::AdamOptions(o.learningRate));
  Discriminator disc(d.n, o.discriminatorWidth, o.arch.condDim);
  torch::optim::Adam discOpt(disc->parameters(), torch::optim::AdamOptions(2e-4).betas({0.5, 0.999}));
  const GeneratorModel m{gen, latents, opt, disc, discOpt};

  const uint64_t fp = fingerprint(set, o, d);
  int step = 0;
  double err = INFINITY, loss = 0.0;
  TrainedGenerator result;
  torch::serialize::InputArchive ar;
  if (std::optional<int> resumed = openCheckpoint(o.checkpoint, fp, ar, &loss)) {
    step = *resumed;
    loadGeneratorCheckpoint(ar, o, m, stored);
    result.report.resumedFromStep = step;
  }
  auto saveCheckpoint = [&]() { saveGeneratorCheckpoint(o, m, stored, fp, step, loss); };

  // Latents as the decoder will see them: on the int8 / 4-bit grid with quantization in the loop.
  auto inputs = [&](const torch::Tensor& idx) {
    torch::Tensor p = idx.remainder(d.P), k = idx.div(d.P, "floor");
    torch::Tensor z = (stored ? fakeQuantize(latents, o.latentQuantBits) : latents).index_select(0, p);
    return o.arch.condDim > 0 ? torch::cat({z, d.cond.index_select(0, k)}, 1) : z;
  };
  auto evaluate = [&]() {
    return irradianceError(d, [&](const torch::Tensor& idx) { return gen->forward(inputs(idx)); });
  };

  BatchSchedule schedule(d.S, o.batchSize, o.seed);
  std::optional<Progress> progress;
  if (o.showProgress) progress.emplace("train generator", size_t(o.maxSteps), "steps", size_t(step));
  int stepsThisCall = 0;
  bool done = false;
  // Divergence guard: the state of the last finite evaluation (at first the starting weights). A
  // non-finite loss or error stops training and restores it, so the exported model is always finite.
  std::vector<torch::Tensor> trainable = gen->parameters();
  if (stored) trainable.push_back(latents);
  auto snapshot = [&]() { return snapshotOf(trainable); };
  std::vector<torch::Tensor> lastFinite = snapshot();
  auto restoreLastFinite = [&]() {
    restoreFrom(trainable, lastFinite);
    result.report.diverged = true;
  };
  while (step < o.maxSteps && !done) {
    if (InterruptGuard::interrupted() || (o.stopAfterSteps > 0 && stepsThisCall >= o.stopAfterSteps)) {
      result.report.interrupted = true;
      break;
    }
    const float lr = learningRateAt(o, step);
    setGroupLr(opt, 0, lr);
    torch::Tensor idx = schedule.batch(step);
    torch::Tensor y = gen->forward(inputs(idx));
    torch::Tensor ref = d.target.index_select(0, idx);
    torch::Tensor total = reconstructionLoss(y, idx, d, o.loss);
    if (stored && o.loss.latent > 0.0f) total = total + o.loss.latent * latents.pow(2).mean();
    if (!std::isfinite(total.item<double>())) {
      restoreLastFinite();
      break;
    }
    torch::Tensor cond = o.arch.condDim > 0 ? d.cond.index_select(0, idx.div(d.P, "floor")) : torch::Tensor();
    if (o.adversarial) total = total + o.loss.adversarial * adversarialTerm(disc, discOpt, ref, y, cond);
    opt.zero_grad();
    total.backward();
    opt.step();
    loss = total.item<double>();
    if (!afterStep(
            o, "train generator", loss, {step, stepsThisCall, err, done}, evaluate,
            [&] { lastFinite = snapshot(); }, saveCheckpoint, progress)) {
      restoreLastFinite();
      break;
    }
  }
  if (progress) progress->finish();
  const bool keep = o.keepFinishedCheckpoint && !result.report.diverged && step == o.maxSteps;
  closeCheckpoint(result.report.interrupted, keep, o.checkpoint, saveCheckpoint);

  result.weights = exportWeights(gen, o.arch);
  if (stored) result.latents = toVector(fakeQuantize(latents, o.latentQuantBits));
  result.scale = d.scale;
  result.report.steps = step;
  result.report.finalLoss = loss;
  reportCodecError(result.report, evaluateGenerator(result, set), o);
  result.report.seconds = secondsSince(t0);
  return result;
}

// ---- world-shared generator + per-cell adapters ------------------------------------------------------
void SharedTrainingOptions::validate() const {
  training.validate();
  if (training.adversarial)
    fail("SharedTrainingOptions.training.adversarial: not supported by the shared generator");
  if (training.arch.latentSource != LatentSource::Stored)
    fail("SharedTrainingOptions.training.arch: the shared generator needs stored latents");
  if (adapterStages < 0 || adapterStages > training.arch.layers() + 1)
    fail("SharedTrainingOptions.adapterStages = {} outside [0, {}]", adapterStages,
         training.arch.layers() + 1);
  if (!(adapterLearningRate > 0.0f)) fail("SharedTrainingOptions.adapterLearningRate must be > 0");
  if (!(adapterPrior >= 0.0f)) fail("SharedTrainingOptions.adapterPrior must be >= 0");
  if (adapterQuantBits != 0 && adapterQuantBits != 4 && adapterQuantBits != 8)
    fail("SharedTrainingOptions.adapterQuantBits = {}: 0 (off), 4 or 8", adapterQuantBits);
}

TrainedGenerator CellAdaptation::folded(const GeneratorWeights& shared) const {
  TrainedGenerator t;
  t.weights = applyAdapter(shared, adapter);
  t.latents = latents;
  t.scale = scale;
  t.report = report;
  return t;
}

namespace {

// trainShared's inputs: valid, captures of the resolution the model outputs, and a frozen model of the
// options' architecture.
void checkSharedInputs(std::span<const GeneratorTrainingSet> sets, const GeneratorWeights* frozen,
                       const SharedTrainingOptions& so) {
  so.validate();
  const GeneratorTrainingOptions& o = so.training;
  if (sets.empty()) fail("shared generator: no training cells");
  for (size_t c = 0; c < sets.size(); ++c) {
    sets[c].validate();
    if (o.arch.outputResolution() != sets[c].resolution())
      fail("shared generator: cell {} captures are {} x {}, the model outputs {} x {}", c,
           sets[c].resolution(), sets[c].resolution(), o.arch.outputResolution(), o.arch.outputResolution());
  }
  if (frozen) {
    frozen->validate();
    const GeneratorArch &a = frozen->arch, &b = o.arch;
    if (a.latentDim != b.latentDim || a.condDim != b.condDim || a.convChannels != b.convChannels ||
        a.latentSource != b.latentSource)
      fail("shared generator: the options' architecture is not the frozen model's");
  }
}

// What trainShared trains: the one generator, and per cell c its latents[c] ([P][latentDim]) and adapter
// film[c] ([2][adapterFloats]); and what the decoder makes of them.
struct SharedModel {
  const SharedTrainingOptions& so;
  const std::vector<Data>& data;
  int64_t adapterFloats;
  GeneratorNet gen;
  std::vector<torch::Tensor> latents, film;

  // What the decoder sees: latents and adapter on their grids when quantized in the loop.
  torch::Tensor latentsOf(size_t c) const { return fakeQuantize(latents[c], so.training.latentQuantBits); }
  torch::Tensor filmOf(size_t c) const {
    return adapterFloats > 0 ? fakeQuantize(film[c].t(), so.adapterQuantBits).t() : torch::Tensor();
  }
  torch::Tensor forward(size_t c, const torch::Tensor& idx) {
    const Data& d = data[c];
    torch::Tensor z = latentsOf(c).index_select(0, idx.remainder(d.P));
    if (so.training.arch.condDim > 0) z = torch::cat({z, d.cond.index_select(0, idx.div(d.P, "floor"))}, 1);
    return gen->forward(z, filmOf(c), so.adapterStages);
  }
  double evaluate() {
    const size_t C = data.size();
    double sum = 0.0;
    for (size_t c = 0; c < C; ++c)
      sum += irradianceError(data[c], [&](const torch::Tensor& idx) { return forward(c, idx); });
    return sum / double(C);
  }
};

// The optimiser's groups (the shared weights unless frozen, the latents, the adapters) and, in baseLr,
// their learning rates before the schedule.
std::vector<torch::optim::OptimizerParamGroup> sharedParamGroups(SharedModel& m, bool frozen,
                                                                 std::vector<float>& baseLr) {
  const SharedTrainingOptions& so = m.so;
  const GeneratorTrainingOptions& o = so.training;
  std::vector<torch::optim::OptimizerParamGroup> groups;
  if (!frozen) {
    groups.emplace_back(m.gen->parameters(), std::make_unique<torch::optim::AdamOptions>(o.learningRate));
    baseLr.push_back(o.learningRate);
  }
  groups.emplace_back(m.latents, std::make_unique<torch::optim::AdamOptions>(o.latentLearningRate));
  baseLr.push_back(o.latentLearningRate);
  if (m.adapterFloats > 0) {
    groups.emplace_back(m.film, std::make_unique<torch::optim::AdamOptions>(so.adapterLearningRate));
    baseLr.push_back(so.adapterLearningRate);
  }
  return groups;
}

uint64_t sharedFingerprint(std::span<const GeneratorTrainingSet> sets, const std::vector<Data>& data,
                           const GeneratorWeights* frozen, const SharedTrainingOptions& so) {
  const GeneratorTrainingOptions& o = so.training;
  const size_t C = sets.size();
  uint64_t fp = fnv1aValue(kFnv1aOffset, uint64_t(C));
  for (size_t c = 0; c < C; ++c) fp = fnv1aValue(fp, fingerprint(sets[c], o, data[c]));
  for (int v : {so.adapterStages, so.adapterQuantBits}) fp = fnv1aValue(fp, v);
  for (float v : {so.adapterLearningRate, so.adapterPrior}) fp = fnv1aValue(fp, v);
  fp = fnv1aValue(fp, frozen ? weightsContentHash(*frozen) : uint64_t(0));
  return fp;
}

void loadSharedCheckpoint(torch::serialize::InputArchive& ar, SharedModel& m, torch::optim::Adam& opt,
                          bool frozen) {
  torch::NoGradGuard noGrad;
  if (!frozen) {
    torch::serialize::InputArchive g;
    ar.read("gen", g);
    m.gen->load(g);
  }
  for (size_t c = 0; c < m.data.size(); ++c) {
    torch::Tensor z, f;
    ar.read("latents" + std::to_string(c), z);
    ar.read("film" + std::to_string(c), f);
    m.latents[c].copy_(z);
    m.film[c].copy_(f);
  }
  torch::serialize::InputArchive og;
  ar.read("opt", og);
  opt.load(og);
}

void saveSharedCheckpoint(SharedModel& m, torch::optim::Adam& opt, bool frozen, uint64_t fp, int step,
                          double loss) {
  const GeneratorTrainingOptions& o = m.so.training;
  if (o.checkpoint.empty()) return;
  torch::serialize::OutputArchive out, og;
  if (!frozen) {
    torch::serialize::OutputArchive g;
    m.gen->save(g);
    out.write("gen", g);
  }
  for (size_t c = 0; c < m.data.size(); ++c) {
    out.write("latents" + std::to_string(c), m.latents[c].detach());
    out.write("film" + std::to_string(c), m.film[c].detach());
  }
  opt.save(og);
  out.write("opt", og);
  saveCheckpointArchive(o.checkpoint, fp, step, loss, out);
}

// One step's loss: each cell's reconstruction and priors on its batch, averaged over the cells.
torch::Tensor sharedStepLoss(SharedModel& m, std::vector<BatchSchedule>& schedules, int step) {
  const SharedTrainingOptions& so = m.so;
  const GeneratorTrainingOptions& o = so.training;
  const size_t C = m.data.size();
  torch::Tensor total = torch::zeros({});
  for (size_t c = 0; c < C; ++c) {
    torch::Tensor idx = schedules[c].batch(step);
    torch::Tensor l = reconstructionLoss(m.forward(c, idx), idx, m.data[c], o.loss);
    if (o.loss.latent > 0.0f) l = l + o.loss.latent * m.latents[c].pow(2).mean();
    if (m.adapterFloats > 0 && so.adapterPrior > 0.0f) l = l + so.adapterPrior * m.film[c].pow(2).mean();
    total = total + l / double(C);
  }
  return total;
}

// Every cell's adaptation to result.weights, its errors measured through the core decoder, and the means
// of those errors in result.report.
void reportSharedCells(SharedGenerator& result, const SharedModel& m,
                       std::span<const GeneratorTrainingSet> sets, int step, double loss) {
  const SharedTrainingOptions& so = m.so;
  const GeneratorTrainingOptions& o = so.training;
  const size_t C = sets.size();
  const uint64_t sharedHash = weightsContentHash(result.weights);
  double irr = 0.0, rad = 0.0, psnrDb = 0.0;
  for (size_t c = 0; c < C; ++c) {
    CellAdaptation a;
    a.latents = toVector(m.latentsOf(c));
    a.adapter.stages = so.adapterStages;
    if (m.adapterFloats > 0) {
      const torch::Tensor f = m.filmOf(c);
      a.adapter.scale = toVector(f[0]);
      a.adapter.shift = toVector(f[1]);
    }
    a.scale = m.data[c].scale;
    a.sharedWeightsHash = sharedHash;
    a.report.steps = step;
    a.report.resumedFromStep = result.report.resumedFromStep;
    a.report.interrupted = result.report.interrupted;
    a.report.diverged = result.report.diverged;
    a.report.finalLoss = loss;
    const CodecError ce = evaluateGenerator(a.folded(result.weights), sets[c]);
    reportCodecError(a.report, ce, o);
    irr += ce.irradianceRelativeRms / double(C);
    rad += ce.radianceRelativeRms / double(C);
    psnrDb += ce.radiancePsnrDb / double(C);
    result.cells.push_back(std::move(a));
  }
  result.report.steps = step;
  result.report.finalLoss = loss;
  result.report.irradianceRelativeRms = irr;
  result.report.radianceRelativeRms = rad;
  result.report.radiancePsnrDb = psnrDb;
  result.report.reachedTarget = irr <= o.irradianceErrorTarget;
}

// The one training loop of the shared model: pre-training (frozen == nullptr: shared weights trained
// with every cell's latents and adapter) and a frozen fit (one or more cells against fixed weights).
SharedGenerator trainShared(std::span<const GeneratorTrainingSet> sets, const GeneratorWeights* frozen,
                            const SharedTrainingOptions& so) {
  const auto t0 = std::chrono::steady_clock::now();
  checkSharedInputs(sets, frozen, so);
  const GeneratorTrainingOptions& o = so.training;
  setThreads(o.threads);
  torch::manual_seed(o.seed);
  std::vector<Data> data;
  for (const GeneratorTrainingSet& set : sets) data.push_back(makeData(set, o));
  const size_t C = sets.size();
  const int64_t adapterFloats = int64_t(adapterChannels(o.arch, so.adapterStages));

  SharedModel m{so, data, adapterFloats, GeneratorNet(o.arch), {}, {}};
  if (frozen) {
    importWeights(m.gen, *frozen);
    for (torch::Tensor& p : m.gen->parameters()) p.requires_grad_(false);
  }
  for (const Data& d : data) {
    m.latents.push_back((torch::randn({d.P, o.arch.latentDim}) * 0.1).requires_grad_(true));
    m.film.push_back(torch::zeros({2, adapterFloats}).requires_grad_(true));
  }
  std::vector<float> baseLr;
  torch::optim::Adam opt(sharedParamGroups(m, frozen, baseLr), torch::optim::AdamOptions(o.learningRate));

  const uint64_t fp = sharedFingerprint(sets, data, frozen, so);
  int step = 0;
  double err = INFINITY, loss = 0.0;
  SharedGenerator result;
  torch::serialize::InputArchive ar;
  if (std::optional<int> resumed = openCheckpoint(o.checkpoint, fp, ar, &loss)) {
    step = *resumed;
    loadSharedCheckpoint(ar, m, opt, frozen);
    result.report.resumedFromStep = step;
  }
  auto saveCheckpoint = [&]() { saveSharedCheckpoint(m, opt, frozen, fp, step, loss); };
  auto evaluate = [&]() { return m.evaluate(); };

  std::vector<BatchSchedule> schedules;
  for (size_t c = 0; c < C; ++c) schedules.emplace_back(data[c].S, o.batchSize, o.seed + c);
  std::vector<torch::Tensor> trainable = m.latents;
  trainable.insert(trainable.end(), m.film.begin(), m.film.end());
  if (!frozen)
    for (const torch::Tensor& p : m.gen->parameters()) trainable.push_back(p);
  std::vector<torch::Tensor> lastFinite = snapshotOf(trainable);
  auto restoreLastFinite = [&]() {
    restoreFrom(trainable, lastFinite);
    result.report.diverged = true;
  };
  std::optional<Progress> progress;
  const char* label = frozen ? "fit cell adapter" : "pretrain shared generator";
  if (o.showProgress) progress.emplace(label, size_t(o.maxSteps), "steps", size_t(step));
  int stepsThisCall = 0;
  bool done = false;
  while (step < o.maxSteps && !done) {
    if (InterruptGuard::interrupted() || (o.stopAfterSteps > 0 && stepsThisCall >= o.stopAfterSteps)) {
      result.report.interrupted = true;
      break;
    }
    const float factor = learningRateAt(o, step) / o.learningRate;
    for (size_t g = 0; g < baseLr.size(); ++g) setGroupLr(opt, g, baseLr[g] * factor);
    torch::Tensor total = sharedStepLoss(m, schedules, step);
    if (!std::isfinite(total.item<double>())) {
      restoreLastFinite();
      break;
    }
    opt.zero_grad();
    total.backward();
    opt.step();
    loss = total.item<double>();
    if (!afterStep(
            o, label, loss, {step, stepsThisCall, err, done}, evaluate,
            [&] { lastFinite = snapshotOf(trainable); }, saveCheckpoint, progress)) {
      restoreLastFinite();
      break;
    }
  }
  if (progress) progress->finish();
  closeCheckpoint(result.report.interrupted, false, o.checkpoint, saveCheckpoint);

  result.weights = exportWeights(m.gen, o.arch);
  reportSharedCells(result, m, sets, step, loss);
  result.report.seconds = secondsSince(t0);
  for (CellAdaptation& a : result.cells) a.report.seconds = result.report.seconds;
  return result;
}

}  // namespace

SharedGenerator pretrainSharedGenerator(std::span<const GeneratorTrainingSet> cells,
                                        const SharedTrainingOptions& options) {
  return trainShared(cells, nullptr, options);
}

CellAdaptation fitCellToSharedGenerator(const GeneratorWeights& shared, const GeneratorTrainingSet& cell,
                                        const SharedTrainingOptions& options) {
  SharedGenerator r = trainShared(std::span<const GeneratorTrainingSet>(&cell, 1), &shared, options);
  return std::move(r.cells.front());
}

std::vector<float> torchGeneratorForward(const GeneratorWeights& weights, std::span<const float> latents,
                                         std::span<const float> cond, size_t count,
                                         const GeneratorAdapter* adapter) {
  weights.validate();
  const GeneratorArch& a = weights.arch;
  if (latents.size() != count * size_t(a.latentDim))
    fail("torchGeneratorForward: {} latent floats for {} probes of {}", latents.size(), count, a.latentDim);
  if (cond.size() != size_t(a.condDim))
    fail("torchGeneratorForward: {} conditioning floats, the model takes {}", cond.size(), a.condDim);
  torch::NoGradGuard noGrad;
  GeneratorNet net(a);
  importWeights(net, weights);
  torch::Tensor z =
      torch::from_blob(const_cast<float*>(latents.data()), {int64_t(count), a.latentDim}, torch::kFloat32);
  if (a.condDim > 0) {
    torch::Tensor c = torch::from_blob(const_cast<float*>(cond.data()), {1, a.condDim}, torch::kFloat32)
                          .expand({int64_t(count), a.condDim});
    z = torch::cat({z, c}, 1);
  }
  if (!adapter) return toVector(net->forward(z));
  adapter->validate(a);
  if (adapter->scale.empty()) return toVector(net->forward(z));
  const int64_t n = int64_t(adapter->scale.size());
  torch::Tensor film =
      torch::cat({fromVector(adapter->scale, {1, n}), fromVector(adapter->shift, {1, n})}, 0);
  return toVector(net->forward(z, film, adapter->stages));
}

// ---- metrics ---------------------------------------------------------------------------------------
CodecError codecError(const GeneratorTrainingSet& set, std::span<const std::vector<float>> decoded) {
  set.validate();
  if (decoded.size() != set.keys.size())
    fail("codecError: {} decoded keys for {} lighting keys", decoded.size(), set.keys.size());
  const int n = set.resolution(), m = set.irradianceResolution();
  const size_t T = size_t(n) * size_t(n), M = size_t(m) * size_t(m), P = set.probeCount();
  const std::vector<double> k = irradianceKernel(n, m);
  double num = 0.0, den = 0.0;
  std::vector<float> ref, dec;
  ref.reserve(set.keys.size() * P * T * 3);
  dec.reserve(ref.capacity());
  std::vector<double> ea(M * 3), eb(M * 3);
  for (size_t key = 0; key < set.keys.size(); ++key) {
    if (decoded[key].size() != P * T * 3)
      fail("codecError: decoded key {} holds {} floats, need {}", key, decoded[key].size(), P * T * 3);
    for (size_t p = 0; p < P; ++p) {
      const float* a = &decoded[key][p * T * 3];
      const std::vector<float>& b = set.keys[key].probes[p].radiance;
      std::fill(ea.begin(), ea.end(), 0.0);
      std::fill(eb.begin(), eb.end(), 0.0);
      for (size_t t = 0; t < T; ++t)
        for (size_t q = 0; q < M; ++q) {
          const double w = k[t * M + q];
          if (w == 0.0) continue;
          for (size_t c = 0; c < 3; ++c) {
            ea[q * 3 + c] += w * a[t * 3 + c];
            eb[q * 3 + c] += w * b[t * 3 + c];
          }
        }
      for (size_t i = 0; i < M * 3; ++i) {
        num += (ea[i] - eb[i]) * (ea[i] - eb[i]);
        den += eb[i] * eb[i];
      }
      ref.insert(ref.end(), b.begin(), b.end());
      dec.insert(dec.end(), a, a + T * 3);
    }
  }
  CodecError e;
  e.irradianceRelativeRms = den > 0.0 ? std::sqrt(num / den) : (num > 0.0 ? INFINITY : 0.0);
  e.radianceRelativeRms = relativeRms(dec, ref);
  const float peak = *std::max_element(ref.begin(), ref.end());
  e.radiancePsnrDb = peak > 0.0f ? psnr(dec, ref, peak) : 0.0;
  return e;
}

CodecError evaluateGenerator(const TrainedGenerator& model, const GeneratorTrainingSet& set) {
  const GeneratorArch& a = model.weights.arch;
  const size_t P = set.probeCount();
  const int R = a.outputResolution();
  const size_t T = size_t(R) * size_t(R);
  const std::vector<float> z = model.decoderLatents(set);
  std::vector<std::vector<float>> decoded(set.keys.size());
  std::vector<float> raw(P * size_t(a.outChannels()) * T);
  for (size_t k = 0; k < set.keys.size(); ++k) {
    const auto c = conditioningVector(set.keys[k].timeOfDayHours, set.keys[k].weather);
    generatorForward(model.weights, z, std::span<const float>(c.data(), size_t(a.condDim)), P, raw);
    decoded[k].resize(P * T * 3);
    for (size_t p = 0; p < P; ++p)
      decodeChannels(std::span<const float>(raw).subspan(p * size_t(kGeneratorChannels) * T,
                                                         size_t(kGeneratorChannels) * T),
                     R, model.scale, std::span<float>(decoded[k]).subspan(p * T * 3, T * 3), {}, {}, {});
  }
  return codecError(set, decoded);
}

// ---- model sizing ----------------------------------------------------------------------------------
std::string_view cellModelKindName(CellModelKind k) {
  switch (k) {
    case CellModelKind::kConstant:
      return "constant";
    case CellModelKind::kShL1:
      return "sh-l1";
    case CellModelKind::kGenerator:
      return "generator";
    case CellModelKind::kShL2:
      return "sh-l2";
  }
  return "unknown";
}

std::string CellModelChoice::describe() const {
  if (kind != CellModelKind::kGenerator || !generator)
    return "no network: " + std::string(cellModelKindName(kind));
  const GeneratorArch& a = generator->weights.arch;
  std::string s = a.latentSource == LatentSource::Stored ? "z" + std::to_string(a.latentDim)
                                                         : "pos" + std::to_string(a.fourierOctaves);
  s += " C";
  for (size_t i = 0; i + 1 < a.convChannels.size(); ++i)
    s += (i ? "-" : "") + std::to_string(a.convChannels[i]);
  return s + (a.latentSource == LatentSource::Stored ? " (stored latents)" : " (position latents)");
}

std::vector<GeneratorArch> sizingCandidates(int resolution, LatentSource source) {
  int k = 0;
  while ((kBase << k) < resolution) ++k;
  if ((kBase << k) != resolution || k < 1 || k > 5)
    fail("sizingCandidates: resolution {} is not 4 * 2^k with k in [1, 5]", resolution);
  std::vector<GeneratorArch> out;
  for (int width : {8, 16, 32, 64})
    for (int size : {1, 2, 3}) {
      GeneratorArch a;
      a.latentSource = source;
      if (source == LatentSource::PositionFourier) {
        a.fourierOctaves = size;
        a.latentDim = 6 * size;
      } else {
        a.latentDim = 4 << (size - 1);
      }
      a.convChannels.clear();
      for (int i = 0; i < k; ++i) a.convChannels.push_back(std::max(width >> i, 8));
      a.convChannels.push_back(kGeneratorChannels);
      out.push_back(a);
    }
  return out;
}

size_t generatorBytes(const GeneratorArch& arch, size_t probeCount) {
  const size_t latents = arch.latentSource == LatentSource::Stored ? probeCount * size_t(arch.latentDim) : 0;
  return 4 * (arch.parameterCount() + latents) + sizeof(GeneratorOutputScale);
}

namespace {

// Cell-wide no-network models per key: the solid-angle mean radiance (constant) or the mean SH L1
// projection over the cell's probes; decoded maps are that function at every probe.
struct NoNetwork {
  std::vector<float> lighting;
  std::vector<std::vector<float>> decoded;
};

template <int N>
void fitSh(const LightingKey& key, int n, std::vector<float>& lighting, std::vector<float>& map) {
  ShRgb<N> sum;
  for (const ProbeCapture& c : key.probes) {
    const ShRgb<N> s = shProject<N>(c.radiance, n);
    for (int i = 0; i < N; ++i) sum.c[size_t(i)] += s.c[size_t(i)];
  }
  for (auto& c : sum.c) c /= float(key.probes.size());
  for (const glm::vec3& c : sum.c) lighting.insert(lighting.end(), {c.x, c.y, c.z});
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const glm::vec3 v = shEvaluate(sum, octTexelDirection(i, j, n));
      for (int ch = 0; ch < 3; ++ch) map[size_t(j * n + i) * 3 + size_t(ch)] = v[ch];
    }
}

NoNetwork fitNoNetwork(const GeneratorTrainingSet& set, CellModelKind kind) {
  const int n = set.resolution();
  const size_t T = size_t(n) * size_t(n), P = set.probeCount();
  const std::vector<double> omega = octTexelSolidAngles(n);
  NoNetwork r;
  for (const LightingKey& key : set.keys) {
    std::vector<float> map(T * 3);
    if (kind == CellModelKind::kConstant) {
      glm::dvec3 mean(0.0);
      for (const ProbeCapture& c : key.probes)
        for (size_t t = 0; t < T; ++t)
          for (int ch = 0; ch < 3; ++ch) mean[ch] += omega[t] * c.radiance[t * 3 + size_t(ch)];
      mean /= 4.0 * std::numbers::pi * double(P);
      for (int ch = 0; ch < 3; ++ch) r.lighting.push_back(float(mean[ch]));
      for (size_t t = 0; t < T; ++t)
        for (int ch = 0; ch < 3; ++ch) map[t * 3 + size_t(ch)] = float(mean[ch]);
    } else if (kind == CellModelKind::kShL1) {
      fitSh<4>(key, n, r.lighting, map);
    } else {
      fitSh<9>(key, n, r.lighting, map);
    }
    std::vector<float> all;
    all.reserve(P * T * 3);
    for (size_t p = 0; p < P; ++p) all.insert(all.end(), map.begin(), map.end());
    r.decoded.push_back(std::move(all));
  }
  return r;
}

}  // namespace

namespace {

// The no-network part of chooseCellModel: the first of options.noNetworkKinds that meets the target, else
// (all probes sky-only) the most accurate of them, else nullopt with the attempts recorded in `choice` and
// the no-network fits in `fits` (chooseCellModel's last resort).
std::optional<CellModelChoice> noNetworkChoice(const GeneratorTrainingSet& set,
                                               std::span<const uint8_t> probeFlags,
                                               const ModelSizingOptions& options, CellModelChoice& choice,
                                               std::chrono::steady_clock::time_point t0,
                                               std::vector<CellModelChoice>& fits) {
  set.validate();
  if (!probeFlags.empty() && probeFlags.size() != set.probeCount())
    fail("chooseCellModel: {} probe flags for {} probes", probeFlags.size(), set.probeCount());
  const double target = options.irradianceErrorTarget;
  choice.errorTarget = target;

  bool allSky = !probeFlags.empty();
  for (uint8_t f : probeFlags)
    if (!(f & worlds::kProbeDisabledSolid) && !(f & worlds::kProbeSkyOnly)) allSky = false;

  fits.clear();
  for (CellModelKind kind : options.noNetworkKinds) {
    if (kind == CellModelKind::kGenerator) fail("ModelSizingOptions.noNetworkKinds lists the generator");
    const auto ts = std::chrono::steady_clock::now();
    NoNetwork nn = fitNoNetwork(set, kind);
    CellModelChoice c;
    c.kind = kind;
    c.lighting = std::move(nn.lighting);
    c.error = codecError(set, nn.decoded);
    c.bytes = 4 * c.lighting.size();
    c.reachedTarget = c.error.irradianceRelativeRms <= target;
    choice.attempts.push_back(
        SizingAttempt{kind, {}, c.bytes, c.error.irradianceRelativeRms, secondsSince(ts), 0, 0});
    fits.push_back(std::move(c));
  }
  auto finish = [&](CellModelChoice c) {
    c.errorTarget = target;
    c.attempts = std::move(choice.attempts);
    c.trainingSeconds = secondsSince(t0);
    return c;
  };
  for (CellModelChoice& c : fits)
    if (c.reachedTarget) return finish(std::move(c));
  if (allSky && !fits.empty()) {
    size_t best = 0;
    for (size_t i = 1; i < fits.size(); ++i)
      if (fits[i].error.irradianceRelativeRms < fits[best].error.irradianceRelativeRms) best = i;
    return finish(std::move(fits[best]));
  }
  return std::nullopt;
}

}  // namespace

std::optional<CellModelChoice> chooseNoNetworkModel(const GeneratorTrainingSet& set,
                                                    std::span<const uint8_t> probeFlags,
                                                    const ModelSizingOptions& options) {
  CellModelChoice attempts;
  std::vector<CellModelChoice> fits;
  return noNetworkChoice(set, probeFlags, options, attempts, std::chrono::steady_clock::now(), fits);
}

CellModelChoice chooseCellModel(const GeneratorTrainingSet& set, std::span<const uint8_t> probeFlags,
                                const ModelSizingOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  CellModelChoice choice;
  std::vector<CellModelChoice> fits;
  if (std::optional<CellModelChoice> c = noNetworkChoice(set, probeFlags, options, choice, t0, fits))
    return std::move(*c);
  const double target = options.irradianceErrorTarget;
  auto finish = [&](CellModelChoice c) {
    c.errorTarget = target;
    c.attempts = std::move(choice.attempts);
    c.trainingSeconds = secondsSince(t0);
    return c;
  };

  std::vector<GeneratorArch> candidates = options.candidates.empty()
                                              ? sizingCandidates(set.resolution(), options.latentSource)
                                              : options.candidates;
  const size_t P = set.probeCount();
  std::stable_sort(candidates.begin(), candidates.end(), [P](const GeneratorArch& a, const GeneratorArch& b) {
    return generatorBytes(a, P) < generatorBytes(b, P);
  });
  std::optional<CellModelChoice> best;
  bool bestUsable = false;
  for (size_t i = 0; i < candidates.size(); ++i) {
    GeneratorTrainingOptions to = options.training;
    to.arch = candidates[i];
    to.irradianceErrorTarget = target;
    if (!to.checkpoint.empty()) to.checkpoint += ".candidate" + std::to_string(i);
    TrainedGenerator g = trainGenerator(set, to);
    CellModelChoice c;
    c.kind = CellModelKind::kGenerator;
    c.error =
        CodecError{g.report.irradianceRelativeRms, g.report.radianceRelativeRms, g.report.radiancePsnrDb};
    c.parameterCount = to.arch.parameterCount();
    c.latentCount = g.latents.size();
    c.bytes = generatorBytes(to.arch, P);
    c.reachedTarget = g.report.reachedTarget;
    choice.attempts.push_back(SizingAttempt{CellModelKind::kGenerator, to.arch, c.bytes,
                                            c.error.irradianceRelativeRms, g.report.seconds, g.report.steps,
                                            g.report.resumedFromStep});
    const bool interrupted = g.report.interrupted;
    // A diverged network (or a non-finite error) is kept only when there is nothing else at all.
    const bool usable = !g.report.diverged && std::isfinite(c.error.irradianceRelativeRms);
    c.generator = std::move(g);
    if (c.reachedTarget && usable) return finish(std::move(c));
    if (!best ||
        (usable && (!bestUsable || c.error.irradianceRelativeRms < best->error.irradianceRelativeRms))) {
      best = std::move(c);
      bestUsable = usable;
    }
    if (interrupted) break;
  }
  for (CellModelChoice& c : fits)
    if (!best || !bestUsable || c.error.irradianceRelativeRms < best->error.irradianceRelativeRms) {
      best = std::move(c);
      bestUsable = true;
    }
  return finish(std::move(*best));
}

}  // namespace lfgi::bake
