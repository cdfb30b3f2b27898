// Training of the per-cell generative probe codec (docs/DESIGN.md §4; the network is core/generator.h) and
// the choice of the smallest model that meets a cell's error target. The only libtorch user; libtorch stays
// inside generator_training.cpp (nothing here includes it).
//
// Method: auto-decoder / generative latent optimisation (Bojanowski et al. 2018, "Optimizing the Latent
// Space of Generative Networks"; Park et al. 2019, DeepSDF): every probe's latent z is a free parameter
// optimised jointly with the weights (LatentSource::Stored, L2 prior lambda |z|^2), or z is the fixed
// Fourier feature of the probe's position (LatentSource::PositionFourier, zero latent bytes). One model
// covers several lighting keys (time of day, weather) through conditioningVector(); a training sample
// is one (probe, key) pair. Targets are the encoded channels of core/generator.h.
//
// Loss per sample (means over texels; weights in TrainingLossWeights):
//   radiance   solid-angle weighted squared error of log1p(L / exposure) (relative error in log space,
//              weighted as the sphere integral of irradiance weighs it)
//   irradiance mean over the batch's samples s of |E_s(decoded) - E_s|^2 / (|E_s|^2 + f^2 mean |E|^2), E
//              = the irradiance operator below applied to exposure * expm1(clamp(y, 0, 20)), f =
//              irradianceFloor, the mean over the probes of the sample's key: relative per probe, so a
//              dark room's probes (what keeps its light from leaking) weigh as much as a sunlit one's
//   distance, normal, albedo   squared error of the encoded channels
//   latent     lambda * mean z^2 (Stored only)
//   adversarial (option) non-saturating DCGAN loss of a small conditional discriminator (strided
//              Conv2d + LeakyReLU 0.2 down to 4 x 4, flattened, concatenated with c, one Linear logit)
//              trained on (encoded capture, c) as real and (generator output, c) as fake
// Optimiser: Adam (weights lr, latents latentLr; discriminator 2e-4, betas 0.5/0.999 as in DCGAN);
// the weight learning rate halves at 60 % and 85 % of maxSteps.
//
// Error metric (the stop criterion and CodecError): irradiance relative RMS, sqrt(sum |E' - E|^2 /
// sum |E|^2) over every probe, key, irradiance texel and channel, where E(normal) = sum_texels L
// max(0, normal . w) Omega (exact texel solid angles, normals = the irradianceResolution map's texel
// centres) is applied to both the decoded and the captured radiance maps. So it is the codec's error
// alone (the texel discretisation is the same on both sides), on the light shading reads from probes
// (training sets hold no directly seen discs, captureTrainingSet).
//
// Determinism: torch's generator is seeded with `seed` before the weights are created, latents are
// initialised from it, minibatches are a fixed function of (seed, epoch). Same seed, data, options and
// thread count -> bit-identical exported weights (tested with 1 thread; libtorch's CPU kernels and
// OpenBLAS may reduce in a thread-count dependent order).
// Resume: with a checkpoint path, the whole state (weights, latents, discriminator, both Adam states,
// step) is written atomically every checkpointEvery steps and when interrupted (polls core/progress.h
// InterruptGuard::interrupted() between steps; the caller installs the guard); a run that finds the
// checkpoint continues from it and ends bit-identical to an uninterrupted run (tested). A checkpoint written
// for other data or options is an error.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "bake/probe_capture.h"
#include "core/generator.h"

namespace lfgi::bake {

// One lighting key of a cell: the captures of every training probe under it.
struct LightingKey {
  float timeOfDayHours = 12.0f;
  float weather = 0.0f;              // overcast, [0, 1]
  std::vector<ProbeCapture> probes;  // the same probes in the same order in every key
};

struct GeneratorTrainingSet {
  // Per probe: position normalised to [0, 1]^3 in the cell's probe box (PositionFourier latents).
  std::vector<glm::vec3> positions01;
  std::vector<LightingKey> keys;

  size_t probeCount() const { return positions01.size(); }
  int resolution() const;            // radiance map side n of the captures
  int irradianceResolution() const;  // m of the irradiance metric
  // Throws lfgi::Error unless there is >= 1 key and >= 1 probe, every key holds positions01.size()
  // captures, and all captures share n and m and hold full maps.
  void validate() const;
  // FNV-1a of the keys, positions and every capture's contentHash().
  uint64_t contentHash() const;
};

struct TrainingLossWeights {
  float radiance = 1.0f;
  float irradiance = 1.0f;
  float distance = 0.5f;
  float normal = 0.25f;
  float albedo = 0.25f;
  float latent = 1e-4f;
  float adversarial = 0.02f;  // used only with GeneratorTrainingOptions::adversarial
  // The irradiance term's floor f: each sample's error is relative to |E_s|^2 + f^2 (its key's mean
  // |E|^2), so a dark probe is held to f of the key's mean probe irradiance rather than lost in the bright
  // ones (f = 0.01: the sealed room of worlds/leak_scene.h stays within its 1 % leak bound).
  float irradianceFloor = 0.03f;
};

struct GeneratorTrainingOptions {
  GeneratorArch arch;  // outputResolution() must equal the captures' n
  int maxSteps = 3000;
  double irradianceErrorTarget = 0.05;  // stop when the irradiance relative RMS is <= this
  int evalEvery = 100;                  // steps between error evaluations (and progress lines)
  float learningRate = 3e-3f;
  float latentLearningRate = 1e-2f;
  TrainingLossWeights loss;
  bool adversarial = false;
  int discriminatorWidth = 16;  // channels of the discriminator's first conv
  int batchSize = 256;          // (probe, key) samples per step; >= all samples: full batch
  uint64_t seed = 1;
  int threads = 1;                   // libtorch intra-op and OpenBLAS threads
  float exposure = 0.0f;             // 0: 0.1 x the mean captured radiance
  float range = 0.0f;                // 0: 1.5 x the 95th percentile of texel mean distances (>= 1 m)
  std::filesystem::path checkpoint;  // empty: no checkpoints, no resume
  int checkpointEvery = 500;
  int stopAfterSteps = 0;  // > 0: return (checkpointed, interrupted = true) after this many
                           // steps of this call, as an interrupt would (for resume tests)
  // trainGenerator: a run that took all maxSteps (not diverged) leaves its final state at `checkpoint`
  // instead of removing it, so a rerun returns the same model without training (chooseCellModel's
  // finished candidates, when a bake resumes a cell's search); the caller removes it.
  bool keepFinishedCheckpoint = false;
  bool showProgress = false;  // progress and errors on stderr
  // Quantizer in the loop: 0 off; 4 or 8: Stored latents pass through straight-through fake
  // quantization (core/quantize.h's symmetric per-dimension grid) in every forward pass, and the
  // exported latents are those grid values, so quantizeLatents(latents, dim, bits) is lossless on them.
  int latentQuantBits = 0;
  // Throws lfgi::Error naming the bad field.
  void validate() const;
};

struct GeneratorTrainingReport {
  int steps = 0;            // optimisation steps taken in total (resumed ones included)
  int resumedFromStep = 0;  // 0: started fresh
  bool reachedTarget = false;
  bool interrupted = false;  // stopped by InterruptGuard or stopAfterSteps (checkpoint written)
  bool diverged = false;     // the loss or the error went non-finite: training stopped and the
                             // last finite state (last finite evaluation, else the initial
                             // weights) is what was exported; chooseCellModel never prefers it
  double seconds = 0.0;      // wall time of this call
  double finalLoss = 0.0;
  double irradianceRelativeRms = 0.0;  // of the exported model through core generatorForward
  double radianceRelativeRms = 0.0;
  double radiancePsnrDb = 0.0;
};

struct TrainedGenerator {
  GeneratorWeights weights;
  std::vector<float> latents;  // probeCount * latentDim for Stored; empty for PositionFourier
  GeneratorOutputScale scale;
  GeneratorTrainingReport report;
  // The latent the decoder feeds for probe i (stored, or positionLatent of positions01[i]).
  std::vector<float> decoderLatents(const GeneratorTrainingSet& set) const;
};

TrainedGenerator trainGenerator(const GeneratorTrainingSet& set, const GeneratorTrainingOptions& options);

// ---------------------------------------------------------------------------------------------------
// World-shared generator + per-cell adapters (docs/DESIGN.md §4: "judge a world-shared pre-trained generator
// (cells keep only latents + a small per-cell adapter) against fully per-cell weights").
//
// pretrainSharedGenerator fits one network of training.arch to several cells at once: every cell has its
// own stored latents, its own GeneratorOutputScale (exposure, range: the same automatic choice as
// trainGenerator) and its own FiLM adapter (core/generator.h GeneratorAdapter, adapterStages stages),
// all learned jointly with the shared weights, so the shared weights learn to be modulated per cell. A
// step takes one minibatch of training.batchSize samples from every cell (each cell's own BatchSchedule)
// and minimises the mean over cells of trainGenerator's loss (+ the latent prior + adapterPrior * mean of
// scale^2 + shift^2); the stop metric is the mean over cells of the irradiance relative RMS.
// fitCellToSharedGenerator keeps the shared weights frozen (no gradient, not in the optimiser, never
// written) and fits only a new cell's latents + adapter: a held-out cell costs latents + ~2 (C0 + C1 ..)
// adapter floats + its output scale, and the bake of a cell optimises a few hundred floats per probe
// batch instead of a whole network.
// Why FiLM and not a low-rank delta on the linear layer: per-channel scale/shift of the first stages is
// the smallest adapter that can re-tint and re-scale every feature map (a cell's overall brightness,
// sky colour, the balance of sky vs bounce), it costs 2 floats per channel (118 for C32-16 with all
// stages vs 35 * 512 * r for a rank-r delta of the z8 linear layer), and it folds exactly into the
// layer's weights and bias (applyAdapter), so the decoders and the GPU kernels run it unchanged.
// Quantizer in the loop: training.latentQuantBits (latents) and adapterQuantBits (adapter) fake-quantize
// with a straight-through gradient; the exported values lie on the grid.
// Conventions are trainGenerator's: Adam, the weight learning rate's halvings at 60 % / 85 % of
// maxSteps (here applied to every group), evaluation every evalEvery steps, stop at the target,
// divergence guard, progress, InterruptGuard / stopAfterSteps, an atomic checkpoint that a rerun resumes
// from bit-identically, determinism for a seed (1 thread).
struct SharedTrainingOptions {
  GeneratorTrainingOptions training;  // arch = the shared model; adversarial must be off
  int adapterStages = 2;              // FiLM on the first stages: 0 none .. arch.layers() + 1 (all)
  float adapterLearningRate = 1e-2f;
  float adapterPrior = 1e-3f;  // weight of mean(scale^2 + shift^2)
  int adapterQuantBits = 0;    // 0: float; 8 (or 4): fake-quantized in the loop
  void validate() const;
};

// One cell's part of a shared model.
struct CellAdaptation {
  std::vector<float> latents;  // probeCount * latentDim (on the grid with latentQuantBits)
  GeneratorAdapter adapter;    // (on the grid with adapterQuantBits)
  GeneratorOutputScale scale;
  GeneratorTrainingReport report;  // errors of folded(shared) through the core decoder
  // weightsContentHash of the shared network as it stood when training ended (fitCellToSharedGenerator:
  // equal to the frozen input's, the fit never writes it).
  uint64_t sharedWeightsHash = 0;
  // The cell's decoder model: applyAdapter(shared, adapter), latents, scale.
  TrainedGenerator folded(const GeneratorWeights& shared) const;
};

struct SharedGenerator {
  GeneratorWeights weights;           // the shared network
  std::vector<CellAdaptation> cells;  // the pre-training cells, in input order
  GeneratorTrainingReport report;     // irradianceRelativeRms etc.: means over the cells
};

SharedGenerator pretrainSharedGenerator(std::span<const GeneratorTrainingSet> cells,
                                        const SharedTrainingOptions& options);
// options.training.arch must equal shared.arch.
CellAdaptation fitCellToSharedGenerator(const GeneratorWeights& shared, const GeneratorTrainingSet& cell,
                                        const SharedTrainingOptions& options);

// Captures a training set: every position under every key (worlds::makeSky of `sky` with the key's time
// and overcast). positions01 = (position - boxMin) / (boxMax - boxMin), clamped to [0, 1] (0.5 on a
// zero-size axis). The maps hold what shading reads from probes: the discs the probe sees directly are
// left out (capture.primaryDiscs is ignored; the shading pass adds them with shadow rays), so the codec
// never spends bits on a one-texel sun it must not decode and its error is measured on the light probes
// give. Throws lfgi::Error if a capture is interrupted.
struct LightingKeySpec {
  float timeOfDayHours = 12.0f;
  float weather = 0.0f;
};
GeneratorTrainingSet captureTrainingSet(const EmbreeScene& scene, std::span<const glm::vec3> positions,
                                        glm::vec3 boxMin, glm::vec3 boxMax,
                                        std::span<const LightingKeySpec> keys, const CaptureOptions& capture,
                                        const worlds::SkyState& sky = {}, bool showProgress = false);

// The same network run by libtorch from exported weights (same argument contract as core
// generatorForward); the test that the CPU reference implements PyTorch's layouts uses it.
// With an adapter, libtorch applies it as FiLM after each adapted layer (not folded).
std::vector<float> torchGeneratorForward(const GeneratorWeights& weights, std::span<const float> latents,
                                         std::span<const float> cond, size_t count,
                                         const GeneratorAdapter* adapter = nullptr);

// Errors of decoded maps against the captures (metric at the top of this file). PSNR: 10 log10(peak^2 /
// MSE) of linear radiance over every texel and channel of every key, peak = the largest captured value.
struct CodecError {
  double irradianceRelativeRms = 0.0;
  double radianceRelativeRms = 0.0;
  double radiancePsnrDb = 0.0;
};
// decoded[k]: key k's radiance maps, probeCount * n*n*3 (the ProbeCapture layout), for every key.
CodecError codecError(const GeneratorTrainingSet& set, std::span<const std::vector<float>> decoded);
// Decodes every probe under every key with core generatorForward + decodeChannels and measures it.
CodecError evaluateGenerator(const TrainedGenerator& model, const GeneratorTrainingSet& set);

// ---------------------------------------------------------------------------------------------------
// Model sizing ("a model no bigger than the scene needs", docs/DESIGN.md §4).
enum class CellModelKind : uint8_t {
  kConstant = 0,   // no network: one RGB radiance per key for the whole cell (solid-angle mean)
  kShL1 = 1,       // no network: one SH L1 radiance (4 x RGB, core/sh.h basis) per key for the whole cell
  kGenerator = 2,  // a trained generator
  kShL2 = 3,       // no network: one SH L2 radiance (9 x RGB) per key for the whole cell (a sunlit sky's
                   // irradiance needs band 2: L1 leaves ~20 % relative RMS, see the tests)
};
std::string_view cellModelKindName(CellModelKind k);

struct SizingAttempt {
  CellModelKind kind = CellModelKind::kConstant;
  GeneratorArch arch;  // kGenerator only
  size_t bytes = 0;    // FP32, see CellModelChoice::bytes
  double irradianceRelativeRms = 0.0;
  double seconds = 0.0;
  int steps = 0;
  int resumedFromStep = 0;  // kGenerator: the checkpoint's step it resumed from (0: trained from the start)
};

// What the cell writer stores about the chosen model.
struct CellModelChoice {
  CellModelKind kind = CellModelKind::kConstant;
  std::vector<float> lighting;                // kConstant: keys * 3; kShL1 / kShL2: keys * 4 (9) * 3, per key
                                              // coefficient-major (core/sh.h order), RGB innermost
  std::optional<TrainedGenerator> generator;  // kGenerator only
  bool reachedTarget = false;
  double errorTarget = 0.0;
  CodecError error;                     // of the chosen model
  size_t parameterCount = 0;            // network floats (0 without a network)
  size_t latentCount = 0;               // stored latent floats
  size_t bytes = 0;                     // FP32: 4 x (parameters + latents + lighting) (+ 8 scale bytes)
  double trainingSeconds = 0.0;         // the whole search
  std::vector<SizingAttempt> attempts;  // in the order tried
  // The model in words for CellBakeStats::model (core/cell_file.h): "z8 C32-16 (stored latents)",
  // "pos3 C32-16 (position latents)" or "no network: SH L1".
  std::string describe() const;
};

struct ModelSizingOptions {
  double irradianceErrorTarget = 0.05;
  // Generator candidates; empty: sizingCandidates(n, latentSource). Tried cheapest first (FP32 bytes
  // with this cell's probe count); the first that meets the target wins, else the one with the lowest
  // error.
  std::vector<GeneratorArch> candidates;
  LatentSource latentSource = LatentSource::Stored;
  // No-network models tried (in this order, cheapest first). The cell file of core/cell_file.h stores
  // one SH L1 fallback per cell: a writer of that format passes {kShL1} and one lighting key.
  std::vector<CellModelKind> noNetworkKinds = {CellModelKind::kConstant, CellModelKind::kShL1,
                                               CellModelKind::kShL2};
  GeneratorTrainingOptions training;  // template: arch and target are replaced per candidate
};

// Widths C0 in {8, 16, 32, 64} (each later stage halves, at least 8) x latent sizes {4, 8, 16} (Stored)
// or Fourier octaves {1, 2, 3} (PositionFourier), depth k = log2(n / 4) fixed by the resolution.
std::vector<GeneratorArch> sizingCandidates(int resolution, LatentSource source);

// FP32 bytes of a generator model for probeCount probes.
size_t generatorBytes(const GeneratorArch& arch, size_t probeCount);

// Chooses the cell's model. probeFlags: worlds::ProbeFlag bits per probe (may be empty): when every
// probe is kProbeSkyOnly the cell gets no network (the cheapest of constant, SH L1, SH L2 that meets the
// target, else the most accurate of them); otherwise a no-network model that meets the target wins
// (cheapest first), then the generator search.
CellModelChoice chooseCellModel(const GeneratorTrainingSet& set, std::span<const uint8_t> probeFlags,
                                const ModelSizingOptions& options);
// The no-network step of chooseCellModel alone (no training): the choice it would return without a
// network (a no-network model meets the target, or every probe is sky-only), else nullopt. The shared
// codec (bake/world_bake.h) fits a cell to the world's shared model when this gives nullopt.
std::optional<CellModelChoice> chooseNoNetworkModel(const GeneratorTrainingSet& set,
                                                    std::span<const uint8_t> probeFlags,
                                                    const ModelSizingOptions& options);

}  // namespace lfgi::bake
