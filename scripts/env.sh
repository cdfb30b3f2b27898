# Sourced by the scripts: environment every lfgi run wants.
#
# OpenBLAS (DYNAMIC_ARCH) picks its kernels from CPUID model numbers; on VMs that hide them it falls back
# to the Prescott (SSE3) kernels, measured 5x slower here (sgemm 1024^3 on 2 cores: ~50 GFLOP/s as
# "Prescott", ~250 as "SkylakeX"). Choose from the ISA flags instead, unless the user already chose.
if [[ -z "${OPENBLAS_CORETYPE:-}" && -r /proc/cpuinfo ]]; then
  if grep -qw avx512f /proc/cpuinfo; then
    export OPENBLAS_CORETYPE=SkylakeX
  elif grep -qw avx2 /proc/cpuinfo; then
    export OPENBLAS_CORETYPE=Haswell
  fi
fi
