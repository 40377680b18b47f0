/* What a gather instruction costs on this machine, against scalar loads (not in CI).
 *
 *   gcc -O2 -mavx512f -mavx512dq -mavx2 bench/gather_cost.c -o /tmp/gather_cost && /tmp/gather_cost
 *
 * Each loop repeats one load pattern from an L1-resident table, its indices opaque to the
 * compiler (an empty asm statement) but independent of the loaded values, so the loop
 * measures throughput. Cycles are calibrated by a chain of dependent integer additions (one
 * cycle each). Where the 2023 "Gather Data Sampling" mitigation is in the microcode, a
 * gather is microcoded and costs about the same whatever its width; volcast's trilinear
 * paths (crates/volcast-render/src/sample/grid/avx2.rs, avx512.rs) therefore read their voxels with scalar loads.
 * bench/peers/README.md, "Loads, not gathers", has the figures. */
#include <immintrin.h>
#include <stdint.h>
#include <stdio.h>
#include <time.h>

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + t.tv_nsec * 1e-9;
}

int main(void) {
  static int64_t data[4096];
  for (int i = 0; i < 4096; i++) data[i] = i & 1;
  const long n = 20000000;
  double t0, t1;
  uint64_t x = 1;
  t0 = now();
  for (long k = 0; k < n; k++)
    __asm__ volatile("add $1, %0\n\tadd $1, %0\n\tadd $1, %0\n\tadd $1, %0" : "+r"(x));
  t1 = now();
  const double cycle = (t1 - t0) / n / 4;
  printf("one cycle: %.3f ns\n", cycle * 1e9);
  int64_t out[8];

  __m512i i8 = _mm512_set_epi64(700, 600, 500, 400, 300, 200, 100, 3), acc = _mm512_setzero_si512();
  t0 = now();
  for (long k = 0; k < n; k++) {
    __asm__ volatile("" : "+v"(i8));
    acc = _mm512_add_epi64(acc, _mm512_i64gather_epi64(i8, data, 8));
  }
  t1 = now();
  _mm512_storeu_si512(out, acc);
  printf("gather, 8 x 64-bit (zmm):         %5.1f cycles (%ld)\n", (t1 - t0) / n / cycle, (long)out[0]);

  __m256i i4 = _mm256_set_epi64x(300, 200, 100, 3), acc4 = _mm256_setzero_si256();
  t0 = now();
  for (long k = 0; k < n; k++) {
    __asm__ volatile("" : "+v"(i4));
    acc4 = _mm256_add_epi64(acc4, _mm256_i64gather_epi64((const long long *)data, i4, 8));
  }
  t1 = now();
  _mm256_storeu_si256((void *)out, acc4);
  printf("gather, 4 x 64-bit (ymm):         %5.1f cycles (%ld)\n", (t1 - t0) / n / cycle, (long)out[0]);

  __m256i i32 = _mm256_set_epi32(700, 600, 500, 400, 300, 200, 100, 3);
  __m256 accf = _mm256_setzero_ps();
  t0 = now();
  for (long k = 0; k < n; k++) {
    __asm__ volatile("" : "+v"(i32));
    accf = _mm256_add_ps(accf, _mm256_i32gather_ps((const float *)data, i32, 4));
  }
  t1 = now();
  float outf[8];
  _mm256_storeu_ps(outf, accf);
  printf("gather, 8 x 32-bit (ymm):         %5.1f cycles (%g)\n", (t1 - t0) / n / cycle, outf[0]);

  int64_t a0 = 3, a1 = 100, a2 = 200, a3 = 300, a4 = 400, a5 = 500, a6 = 600, a7 = 700;
  acc = _mm512_setzero_si512();
  t0 = now();
  for (long k = 0; k < n; k++) {
    __asm__ volatile("" : "+r"(a0), "+r"(a1), "+r"(a2), "+r"(a3), "+r"(a4), "+r"(a5), "+r"(a6), "+r"(a7));
    acc = _mm512_add_epi64(acc, _mm512_set_epi64(data[a7], data[a6], data[a5], data[a4], data[a3],
                                                 data[a2], data[a1], data[a0]));
  }
  t1 = now();
  _mm512_storeu_si512(out, acc);
  printf("8 scalar 64-bit loads into a zmm: %5.1f cycles (%ld)\n", (t1 - t0) / n / cycle, (long)out[0]);

  acc4 = _mm256_setzero_si256();
  t0 = now();
  for (long k = 0; k < n; k++) {
    __asm__ volatile("" : "+r"(a0), "+r"(a1), "+r"(a2), "+r"(a3));
    acc4 = _mm256_add_epi64(acc4, _mm256_set_epi64x(data[a3], data[a2], data[a1], data[a0]));
  }
  t1 = now();
  _mm256_storeu_si256((void *)out, acc4);
  printf("4 scalar 64-bit loads into a ymm: %5.1f cycles (%ld)\n", (t1 - t0) / n / cycle, (long)out[0]);
  return 0;
}
