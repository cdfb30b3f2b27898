// PCA per cell (core/probe_codecs.h): the cell's probes' radiance maps as rows of X (P x D, D = n*n*3),
// mean-centred; principal directions from LAPACK dsyevr (OpenBLAS ships the reference LAPACK) on the Gram
// matrix Xc Xc^T (P <= D, "snapshot" PCA, Sirovich 1987) or the covariance Xc^T Xc (P > D). The energy
// discarded by keeping k components is the sum of the remaining eigenvalues (Eckart-Young), so k for an
// error target comes from the spectrum without trial reconstructions.
#include <algorithm>
#include <cmath>
#include <numeric>

#include <cblas.h>

#include "core/error.h"
#include "core/probe_codecs.h"
#include "core/probe_codecs_internal.h"

// LAPACK (Fortran ABI; Debian 12 has no LAPACKE headers for OpenBLAS, the symbols are in libopenblas).
// The trailing size_t is gfortran's hidden length of each CHARACTER argument.
extern "C" void dsyevr_(const char* jobz, const char* range, const char* uplo, const int* n, double* a,
                        const int* lda, const double* vl, const double* vu, const int* il, const int* iu,
                        const double* abstol, int* m, double* w, double* z, const int* ldz, int* isuppz,
                        double* work, const int* lwork, int* iwork, const int* liwork, int* info, size_t,
                        size_t, size_t);

namespace lfgi {

using namespace codec_detail;

namespace {

// Eigen-decomposition of a symmetric N x N matrix (either triangle filled, row- or column-major alike):
// eigenvalues descending, eigenvectors as rows of `vectors` (N x N, row i for value i).
void symmetricEigen(std::vector<double>& a, int N, std::vector<double>& values,
                    std::vector<double>& vectors) {
  const char jobz = 'V', range = 'A', uplo = 'L';
  const double vl = 0.0, vu = 0.0, abstol = 0.0;
  const int il = 0, iu = 0;
  int m = 0, info = 0;
  std::vector<double> w(static_cast<size_t>(N)), z(static_cast<size_t>(N) * static_cast<size_t>(N));
  std::vector<int> isuppz(2 * static_cast<size_t>(N));
  int lwork = -1, liwork = -1, iworkQuery = 0;
  double workQuery = 0.0;
  dsyevr_(&jobz, &range, &uplo, &N, a.data(), &N, &vl, &vu, &il, &iu, &abstol, &m, w.data(), z.data(), &N,
          isuppz.data(), &workQuery, &lwork, &iworkQuery, &liwork, &info, 1, 1, 1);
  if (info != 0) fail("pca encode: LAPACK dsyevr workspace query failed (info = {})", info);
  lwork = int(workQuery);
  liwork = iworkQuery;
  std::vector<double> work(size_t(std::max(lwork, 1)));
  std::vector<int> iwork(size_t(std::max(liwork, 1)));
  dsyevr_(&jobz, &range, &uplo, &N, a.data(), &N, &vl, &vu, &il, &iu, &abstol, &m, w.data(), z.data(), &N,
          isuppz.data(), work.data(), &lwork, iwork.data(), &liwork, &info, 1, 1, 1);
  if (info != 0 || m != N)
    fail("pca encode: LAPACK dsyevr failed (info = {}, {} of {} eigenvalues)", info, m, N);
  values.resize(size_t(N));
  vectors.resize(size_t(N) * size_t(N));
  for (int i = 0; i < N; ++i) {  // ascending -> descending; column N-1-i of the column-major z
    values[size_t(i)] = std::max(0.0, w[size_t(N - 1 - i)]);
    std::copy_n(z.data() + size_t(N - 1 - i) * size_t(N), N, vectors.data() + size_t(i) * size_t(N));
  }
}

class PcaCodec final : public ProbeCodec {
 public:
  PcaCodec(double target, int maxK) : target_(target), maxK_(maxK) {
    if (!(target > 0.0 && target <= 1.0)) fail("pca codec: error target {} outside (0, 1]", target);
    if (maxK < 1 || maxK > 4096) fail("pca codec: maxComponents {} outside [1, 4096]", maxK);
  }
  std::string name() const override { return "pca"; }
  std::string setting() const override { return fmt::format("target {}", target_); }

  std::vector<std::byte> encode(const ProbeField& f) const override {
    checkField("pca", f);
    const int P = int(f.probeCount());
    const int D = f.resolution * f.resolution * 3;
    std::vector<double> mean(size_t(D), 0.0);
    for (int p = 0; p < P; ++p)
      for (int d = 0; d < D; ++d) mean[size_t(d)] += f.radiance[size_t(p) * size_t(D) + size_t(d)];
    for (double& v : mean) v /= double(P);
    std::vector<double> xc(size_t(P) * size_t(D));
    double total = 0.0;  // energy of the uncentred data: the denominator of the relative RMS
    for (int p = 0; p < P; ++p)
      for (int d = 0; d < D; ++d) {
        const double x = f.radiance[size_t(p) * size_t(D) + size_t(d)];
        xc[size_t(p) * size_t(D) + size_t(d)] = x - mean[size_t(d)];
        total += x * x;
      }

    // Principal directions (rows of `basis`, D long, unit) and their eigenvalues, descending.
    std::vector<double> values, vectors, basis;
    const bool gram = P <= D;
    const int N = gram ? P : D;
    std::vector<double> a(size_t(N) * size_t(N), 0.0);
    if (gram) {
      cblas_dsyrk(CblasRowMajor, CblasUpper, CblasNoTrans, P, D, 1.0, xc.data(), D, 0.0, a.data(), P);
    } else {
      cblas_dsyrk(CblasRowMajor, CblasUpper, CblasTrans, D, P, 1.0, xc.data(), D, 0.0, a.data(), D);
    }
    symmetricEigen(a, N, values, vectors);
    // k: smallest count whose discarded energy meets the target; components with no energy are never kept.
    const double limit = target_ * target_ * total;
    double discarded = std::accumulate(values.begin(), values.end(), 0.0);
    const double tiny = 1e-12 * (values.empty() ? 0.0 : values[0]);
    int k = 0;
    while (k < std::min(N, maxK_) && discarded > limit && values[size_t(k)] > tiny)
      discarded -= values[size_t(k++)];
    basis.assign(size_t(k) * size_t(D), 0.0);
    for (int i = 0; i < k; ++i) {
      double* v = basis.data() + size_t(i) * size_t(D);
      if (gram) {  // v = Xc^T u / sigma
        cblas_dgemv(CblasRowMajor, CblasTrans, P, D, 1.0 / std::sqrt(values[size_t(i)]), xc.data(), D,
                    vectors.data() + size_t(i) * size_t(P), 1, 0.0, v, 1);
      } else {
        std::copy_n(vectors.data() + size_t(i) * size_t(D), D, v);
      }
    }

    // Store the FP16 mean and basis, then project on what the decoder will see so the coefficients absorb
    // the basis rounding.
    ByteWriter w;
    writeHeader(w, {{'L', 'P', 'C', 'A'}, 1, f.resolution, uint32_t(P)});
    w.u16(uint16_t(k));
    std::vector<float> meanF(mean.begin(), mean.end()), basisF(basis.begin(), basis.end());
    w.halves(meanF);
    w.halves(basisF);
    ByteReader back{
        std::span<const std::byte>(w.bytes).subspan(w.bytes.size() - 8 - 2 * (meanF.size() + basisF.size())),
        "pca"};
    back.halves(meanF, "mean");
    back.halves(basisF, "basis");
    std::vector<float> coeff(size_t(P) * size_t(k));
    std::vector<float> centred(static_cast<size_t>(D));
    for (int p = 0; p < P; ++p) {
      for (int d = 0; d < D; ++d)
        centred[size_t(d)] = f.radiance[size_t(p) * size_t(D) + size_t(d)] - meanF[size_t(d)];
      for (int i = 0; i < k; ++i) {
        double dot = 0.0;
        for (int d = 0; d < D; ++d)
          dot += double(centred[size_t(d)]) * basisF[size_t(i) * size_t(D) + size_t(d)];
        coeff[size_t(p) * size_t(k) + size_t(i)] = float(dot);
      }
    }
    w.halves(coeff);
    return std::move(w.bytes);
  }

  void decode(std::span<const std::byte> bytes, ProbeField& out) const override {
    ByteReader r{bytes, "pca"};
    readHeader(r, "LPCA", 1, out);
    const int k = r.u16("component count");
    prepareOut(out);
    const int P = int(out.probeCount());
    const int D = out.resolution * out.resolution * 3;
    std::vector<float> mean(static_cast<size_t>(D)), basis(size_t(k) * size_t(D)),
        coeff(size_t(P) * size_t(k));
    r.halves(mean, "mean");
    r.halves(basis, "basis");
    r.halves(coeff, "coefficients");
    r.expectEnd();
    for (int p = 0; p < P; ++p) std::copy(mean.begin(), mean.end(), out.radiance.begin() + ptrdiff_t(p) * D);
    if (k > 0)
      cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, P, D, k, 1.0f, coeff.data(), k, basis.data(), D,
                  1.0f, out.radiance.data(), D);
  }

 private:
  double target_;
  int maxK_;
};

}  // namespace

std::unique_ptr<ProbeCodec> makePcaCodec(double errorTarget, int maxComponents) {
  return std::make_unique<PcaCodec>(errorTarget, maxComponents);
}

}  // namespace lfgi
