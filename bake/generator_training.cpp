#include "bake/generator_training.h"

#include <dlfcn.h>
#include <torch/torch.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numbers>
#include <random>

#include "core/error.h"
#include "core/file_util.h"
#include "core/metrics.h"
#include "core/octahedral.h"
#include "core/progress.h"
#include "core/sh.h"
#include "worlds/probe_placement.h"

namespace lfgi::bake {

namespace {

constexpr int kBase = 4;

uint64_t fnv(uint64_t h, const void* data, size_t size) {
  const auto* b = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < size; ++i) {
    h ^= b[i];
    h *= 1099511628211ull;
  }
  return h;
}
template <typename T>
uint64_t fnvValue(uint64_t h, const T& v) {
  return fnv(h, &v, sizeof(T));
}
constexpr uint64_t kFnvOffset = 14695981039346656037ull;

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
          torch::nn::ConvTranspose2d(
              torch::nn::ConvTranspose2dOptions(a.convChannels[size_t(i)], a.convChannels[size_t(i) + 1],
                                                kGeneratorKernel)
                  .stride(2)
                  .padding(1))));
  }
  torch::Tensor forward(const torch::Tensor& x) {
    torch::Tensor h = torch::relu(linear->forward(x)).view({-1, c0, kBase, kBase});
    for (size_t i = 0; i < convs.size(); ++i) {
      h = convs[i]->forward(h);
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
  int64_t P = 0, K = 0, S = 0;   // probes, keys, samples (s = k * P + p)
  GeneratorOutputScale scale;
  torch::Tensor target;          // [S][11][n][n] encoded
  torch::Tensor irradiance;      // [S][3][m*m] of the captured radiance
  torch::Tensor kernel;          // [n*n][m*m]
  torch::Tensor radianceWeight;  // [n][n], solid angle normalised to mean 1
  torch::Tensor cond;            // [K][condDim]
  torch::Tensor positionLatents; // [P][L] (PositionFourier)
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
  uint64_t h = fnvValue(kFnvOffset, set.contentHash());
  const GeneratorArch& a = o.arch;
  h = fnvValue(h, a.latentDim);
  h = fnvValue(h, a.condDim);
  for (int c : a.convChannels) h = fnvValue(h, c);
  h = fnvValue(h, uint8_t(a.latentSource));
  h = fnvValue(h, a.fourierOctaves);
  for (float v : {o.learningRate, o.latentLearningRate, o.loss.radiance, o.loss.irradiance, o.loss.distance,
                  o.loss.normal, o.loss.albedo, o.loss.latent, o.loss.adversarial, d.scale.exposure,
                  d.scale.range})
    h = fnvValue(h, v);
  for (int v : {o.maxSteps, o.discriminatorWidth, o.batchSize, int(o.adversarial)}) h = fnvValue(h, v);
  return fnvValue(h, o.seed);
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
        fail("GeneratorTrainingSet.keys[{}].probes[{}]: maps missing or not {} x {} (irradiance {} x {})", k, p,
             n, n, m, m);
    }
  }
  if (n < 8) fail("GeneratorTrainingSet: resolution {} below the generator's smallest output (8)", n);
}

uint64_t GeneratorTrainingSet::contentHash() const {
  uint64_t h = kFnvOffset;
  for (glm::vec3 p : positions01) h = fnvValue(h, p);
  for (const LightingKey& k : keys) {
    h = fnvValue(h, k.timeOfDayHours);
    h = fnvValue(h, k.weather);
    for (const ProbeCapture& c : k.probes) h = fnvValue(h, c.contentHash());
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
  if (discriminatorWidth < 1) fail("GeneratorTrainingOptions.discriminatorWidth = {}: need >= 1", discriminatorWidth);
  if (!(exposure >= 0.0f) || !(range >= 0.0f)) fail("GeneratorTrainingOptions: exposure and range must be >= 0");
  if (checkpointEvery < 1) fail("GeneratorTrainingOptions.checkpointEvery = {}: need >= 1", checkpointEvery);
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
  for (const LightingKeySpec& k : keys) {
    worlds::SkyState s = sky;
    s.timeOfDayHours = k.timeOfDayHours;
    s.overcast = k.weather;
    CaptureResult r = captureProbes(scene, worlds::makeSky(s), positions, capture, showProgress);
    if (r.probesDone != positions.size())
      fail("captureTrainingSet: capture interrupted after {} of {} probes", r.probesDone, positions.size());
    set.keys.push_back(LightingKey{k.timeOfDayHours, k.weather, std::move(r.probes)});
  }
  return set;
}

// ---- training --------------------------------------------------------------------------------------
TrainedGenerator trainGenerator(const GeneratorTrainingSet& set, const GeneratorTrainingOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  set.validate();
  o.validate();
  if (o.arch.outputResolution() != set.resolution())
    fail("GeneratorTrainingOptions.arch: output {} x {} but the captures are {} x {}", o.arch.outputResolution(),
         o.arch.outputResolution(), set.resolution(), set.resolution());
  setThreads(o.threads);
  torch::manual_seed(o.seed);
  const Data d = makeData(set, o);
  const bool stored = o.arch.latentSource == LatentSource::Stored;
  const int64_t T = int64_t(d.n) * d.n;

  GeneratorNet gen(o.arch);
  torch::Tensor latents = stored ? (torch::randn({d.P, o.arch.latentDim}) * 0.1).requires_grad_(true)
                                 : d.positionLatents;
  std::vector<torch::optim::OptimizerParamGroup> groups;
  groups.emplace_back(gen->parameters(), std::make_unique<torch::optim::AdamOptions>(o.learningRate));
  if (stored)
    groups.emplace_back(std::vector<torch::Tensor>{latents},
                        std::make_unique<torch::optim::AdamOptions>(o.latentLearningRate));
  torch::optim::Adam opt(std::move(groups), torch::optim::AdamOptions(o.learningRate));
  Discriminator disc(d.n, o.discriminatorWidth, o.arch.condDim);
  torch::optim::Adam discOpt(disc->parameters(), torch::optim::AdamOptions(2e-4).betas({0.5, 0.999}));

  const uint64_t fp = fingerprint(set, o, d);
  int step = 0;
  TrainedGenerator result;
  if (!o.checkpoint.empty() && std::filesystem::exists(o.checkpoint)) {
    torch::serialize::InputArchive ar;
    try {
      ar.load_from(o.checkpoint.string());
    } catch (const std::exception& e) {
      fail("{}: not a readable training checkpoint ({})", o.checkpoint.string(), e.what());
    }
    torch::Tensor meta;
    ar.read("meta", meta);
    if (meta.numel() != 2 || uint64_t(meta[0].item<int64_t>()) != fp)
      fail("{}: checkpoint of other training data or options (delete it to start over)", o.checkpoint.string());
    step = int(meta[1].item<int64_t>());
    torch::serialize::InputArchive g, og;
    ar.read("gen", g);
    gen->load(g);
    if (stored) {
      torch::NoGradGuard noGrad;
      torch::Tensor z;
      ar.read("latents", z);
      latents.copy_(z);
    }
    ar.read("opt", og);
    opt.load(og);
    if (o.adversarial) {
      torch::serialize::InputArchive dg, dog;
      ar.read("disc", dg);
      disc->load(dg);
      ar.read("discOpt", dog);
      discOpt.load(dog);
    }
    result.report.resumedFromStep = step;
  }
  auto saveCheckpoint = [&]() {
    if (o.checkpoint.empty()) return;
    torch::serialize::OutputArchive ar, g, og;
    ar.write("meta", torch::tensor(std::vector<int64_t>{int64_t(fp), int64_t(step)}, torch::kLong));
    gen->save(g);
    ar.write("gen", g);
    if (stored) ar.write("latents", latents.detach());
    opt.save(og);
    ar.write("opt", og);
    if (o.adversarial) {
      torch::serialize::OutputArchive dg, dog;
      disc->save(dg);
      ar.write("disc", dg);
      discOpt.save(dog);
      ar.write("discOpt", dog);
    }
    writeViaTempFile(o.checkpoint, [&](const std::filesystem::path& tmp) { ar.save_to(tmp.string()); });
  };

  auto inputs = [&](const torch::Tensor& idx) {
    torch::Tensor p = idx.remainder(d.P), k = idx.div(d.P, "floor");
    torch::Tensor z = latents.index_select(0, p);
    return o.arch.condDim > 0 ? torch::cat({z, d.cond.index_select(0, k)}, 1) : z;
  };
  auto predictedIrradiance = [&](const torch::Tensor& y) {
    torch::Tensor L = torch::expm1(y.narrow(1, 0, 3).clamp(0.0, 20.0)) * d.scale.exposure;
    return torch::matmul(L.reshape({y.size(0), 3, T}), d.kernel);
  };
  // Irradiance relative RMS of the current model over the whole set (libtorch forward; the exported
  // model is re-measured with the core decoder at the end).
  auto evaluate = [&]() {
    torch::NoGradGuard noGrad;
    double num = 0.0, den = 0.0;
    for (int64_t s0 = 0; s0 < d.S; s0 += 1024) {
      torch::Tensor idx = torch::arange(s0, std::min(d.S, s0 + 1024), torch::kLong);
      torch::Tensor e = predictedIrradiance(gen->forward(inputs(idx))), ref = d.irradiance.index_select(0, idx);
      num += (e - ref).pow(2).sum().item<double>();
      den += ref.pow(2).sum().item<double>();
    }
    return den > 0.0 ? std::sqrt(num / den) : (num > 0.0 ? INFINITY : 0.0);
  };

  BatchSchedule schedule(d.S, o.batchSize, o.seed);
  std::optional<Progress> progress;
  if (o.showProgress) progress.emplace("train generator", size_t(o.maxSteps), "steps", size_t(step));
  double err = INFINITY, loss = 0.0;
  int stepsThisCall = 0;
  bool done = false;
  // Divergence guard: the state of the last finite evaluation (at first the starting weights). A
  // non-finite loss or error stops training and restores it, so the exported model is always finite.
  auto snapshot = [&]() {
    std::vector<torch::Tensor> st;
    for (const torch::Tensor& p : gen->parameters()) st.push_back(p.detach().clone());
    if (stored) st.push_back(latents.detach().clone());
    return st;
  };
  std::vector<torch::Tensor> lastFinite = snapshot();
  auto restoreLastFinite = [&]() {
    torch::NoGradGuard noGrad;
    std::vector<torch::Tensor> params = gen->parameters();
    for (size_t i = 0; i < params.size(); ++i) params[i].copy_(lastFinite[i]);
    if (stored) latents.copy_(lastFinite.back());
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
    torch::Tensor diff2 = (y - ref).pow(2);
    torch::Tensor total = o.loss.radiance * (diff2.narrow(1, 0, 3) * d.radianceWeight).mean() +
                          o.loss.distance * diff2.narrow(1, 3, 2).mean() +
                          o.loss.normal * diff2.narrow(1, 5, 3).mean() + o.loss.albedo * diff2.narrow(1, 8, 3).mean();
    if (o.loss.irradiance > 0.0f) {
      torch::Tensor eRef = d.irradiance.index_select(0, idx);
      total = total + o.loss.irradiance * (predictedIrradiance(y) - eRef).pow(2).sum() /
                          eRef.pow(2).sum().clamp_min(1e-30);
    }
    if (stored && o.loss.latent > 0.0f) total = total + o.loss.latent * latents.pow(2).mean();
    if (!std::isfinite(total.item<double>())) {
      restoreLastFinite();
      break;
    }
    torch::Tensor cond = o.arch.condDim > 0 ? d.cond.index_select(0, idx.div(d.P, "floor")) : torch::Tensor();
    if (o.adversarial) {
      // Discriminator step on real captures vs the current (detached) outputs, then the generator's
      // non-saturating term (Goodfellow et al. 2014).
      discOpt.zero_grad();
      torch::Tensor real = disc->forward(ref, cond), fake = disc->forward(y.detach(), cond);
      torch::Tensor dLoss = torch::binary_cross_entropy_with_logits(real, torch::ones_like(real)) +
                            torch::binary_cross_entropy_with_logits(fake, torch::zeros_like(fake));
      dLoss.backward();
      discOpt.step();
      torch::Tensor g = disc->forward(y, cond);
      total = total + o.loss.adversarial * torch::binary_cross_entropy_with_logits(g, torch::ones_like(g));
    }
    opt.zero_grad();
    total.backward();
    opt.step();
    loss = total.item<double>();
    ++step;
    ++stepsThisCall;
    if (step % o.evalEvery == 0 || step == o.maxSteps) {
      err = evaluate();
      if (!std::isfinite(err)) {
        restoreLastFinite();
        break;
      }
      lastFinite = snapshot();
      if (o.showProgress)
        std::fprintf(stderr, "\ntrain generator: step %d loss %.5f irradiance rel RMS %.4f (target %.4f)\n", step,
                     loss, err, o.irradianceErrorTarget);
      if (err <= o.irradianceErrorTarget) done = true;
    }
    if (!o.checkpoint.empty() && step % o.checkpointEvery == 0 && !done) saveCheckpoint();
    if (progress) progress->update(size_t(step));
  }
  if (progress) progress->finish();
  if (result.report.interrupted) {
    saveCheckpoint();
  } else if (!o.checkpoint.empty()) {
    // A finished run leaves nothing to resume; its result goes to the caller (the cell file).
    std::error_code ec;
    std::filesystem::remove(o.checkpoint, ec);
  }

  result.weights = exportWeights(gen, o.arch);
  if (stored) result.latents = toVector(latents);
  result.scale = d.scale;
  result.report.steps = step;
  result.report.finalLoss = loss;
  const CodecError ce = evaluateGenerator(result, set);
  result.report.irradianceRelativeRms = ce.irradianceRelativeRms;
  result.report.radianceRelativeRms = ce.radianceRelativeRms;
  result.report.radiancePsnrDb = ce.radiancePsnrDb;
  result.report.reachedTarget = ce.irradianceRelativeRms <= o.irradianceErrorTarget;
  result.report.seconds = secondsSince(t0);
  return result;
}

std::vector<float> torchGeneratorForward(const GeneratorWeights& weights, std::span<const float> latents,
                                         std::span<const float> cond, size_t count) {
  weights.validate();
  const GeneratorArch& a = weights.arch;
  if (latents.size() != count * size_t(a.latentDim))
    fail("torchGeneratorForward: {} latent floats for {} probes of {}", latents.size(), count, a.latentDim);
  if (cond.size() != size_t(a.condDim))
    fail("torchGeneratorForward: {} conditioning floats, the model takes {}", cond.size(), a.condDim);
  torch::NoGradGuard noGrad;
  GeneratorNet net(a);
  importWeights(net, weights);
  torch::Tensor z = torch::from_blob(const_cast<float*>(latents.data()), {int64_t(count), a.latentDim},
                                     torch::kFloat32);
  if (a.condDim > 0) {
    torch::Tensor c = torch::from_blob(const_cast<float*>(cond.data()), {1, a.condDim}, torch::kFloat32)
                          .expand({int64_t(count), a.condDim});
    z = torch::cat({z, c}, 1);
  }
  return toVector(net->forward(z));
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
    case CellModelKind::kConstant: return "constant";
    case CellModelKind::kShL1: return "sh-l1";
    case CellModelKind::kGenerator: return "generator";
    case CellModelKind::kShL2: return "sh-l2";
  }
  return "unknown";
}

std::string CellModelChoice::describe() const {
  if (kind != CellModelKind::kGenerator || !generator) return "no network: " + std::string(cellModelKindName(kind));
  const GeneratorArch& a = generator->weights.arch;
  std::string s = a.latentSource == LatentSource::Stored ? "z" + std::to_string(a.latentDim)
                                                         : "pos" + std::to_string(a.fourierOctaves);
  s += " C";
  for (size_t i = 0; i + 1 < a.convChannels.size(); ++i) s += (i ? "-" : "") + std::to_string(a.convChannels[i]);
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

CellModelChoice chooseCellModel(const GeneratorTrainingSet& set, std::span<const uint8_t> probeFlags,
                                const ModelSizingOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  set.validate();
  if (!probeFlags.empty() && probeFlags.size() != set.probeCount())
    fail("chooseCellModel: {} probe flags for {} probes", probeFlags.size(), set.probeCount());
  const double target = options.irradianceErrorTarget;
  CellModelChoice choice;
  choice.errorTarget = target;

  bool allSky = !probeFlags.empty();
  for (uint8_t f : probeFlags)
    if (!(f & worlds::kProbeDisabledSolid) && !(f & worlds::kProbeSkyOnly)) allSky = false;

  std::vector<CellModelChoice> fits;
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
        SizingAttempt{kind, {}, c.bytes, c.error.irradianceRelativeRms, secondsSince(ts), 0});
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

  std::vector<GeneratorArch> candidates =
      options.candidates.empty() ? sizingCandidates(set.resolution(), options.latentSource) : options.candidates;
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
    c.error = CodecError{g.report.irradianceRelativeRms, g.report.radianceRelativeRms, g.report.radiancePsnrDb};
    c.parameterCount = to.arch.parameterCount();
    c.latentCount = g.latents.size();
    c.bytes = generatorBytes(to.arch, P);
    c.reachedTarget = g.report.reachedTarget;
    choice.attempts.push_back(SizingAttempt{CellModelKind::kGenerator, to.arch, c.bytes,
                                            c.error.irradianceRelativeRms, g.report.seconds, g.report.steps});
    const bool interrupted = g.report.interrupted;
    // A diverged network (or a non-finite error) is kept only when there is nothing else at all.
    const bool usable = !g.report.diverged && std::isfinite(c.error.irradianceRelativeRms);
    c.generator = std::move(g);
    if (c.reachedTarget && usable) return finish(std::move(c));
    if (!best || (usable && (!bestUsable || c.error.irradianceRelativeRms < best->error.irradianceRelativeRms))) {
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
