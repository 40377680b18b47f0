/*
 * volpack_render.c: the peer benchmark's composite mode with VolPack's shear-warp renderer
 * (Debian libvolpack1-dev), orthographic view along +y. Written for this benchmark against
 * volpack.h; run_volpack.py builds and runs it (bench/peers/README.md).
 *
 * Usage: volpack_render VOLUME_U8.nrrd OUT.pgm RENDERS MIN_VOXEL_OPACITY
 * Reads the 256^3 uint8 NRRD (raw data after the blank line), classifies it once with
 * opacity a(v) = 0.2 (v - 0.1) / 0.9 per voxel (VolPack composites one resampled slice per
 * voxel, so along an axis the per-voxel opacity needs no correction) and colour = v (a lookup
 * shader indexed by the value itself: emission only, no lighting), then renders the
 * pre-classified volume RENDERS times and once from the raw volume. Prints
 * "classify S", "render S" (median) and "render_raw S" on stdout; writes the 512x512 8-bit
 * image (premultiplied grey over black) as PGM.
 */
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <volpack.h>

#define N 256
#define IMG 512

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

static int cmp(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static void check(vpContext *vpc, vpResult r, const char *what) {
    if (r != VP_OK) {
        fprintf(stderr, "volpack_render: %s: %s\n", what, vpGetErrorString(vpGetError(vpc)));
        exit(1);
    }
}

static unsigned char *read_volume(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) { perror(path); exit(1); }
    char line[1024];
    int blank = 0;
    while (!blank && fgets(line, sizeof line, f)) blank = (strcmp(line, "\n") == 0);
    unsigned char *v = malloc((size_t)N * N * N);
    if (!blank || !v || fread(v, 1, (size_t)N * N * N, f) != (size_t)N * N * N) {
        fprintf(stderr, "volpack_render: %s: not a 256^3 uint8 raw NRRD\n", path);
        exit(1);
    }
    fclose(f);
    return v;
}

int main(int argc, char **argv) {
    if (argc != 7) {
        fprintf(stderr, "usage: volpack_render VOLUME_U8.nrrd OUT.pgm RENDERS MIN_VOXEL_OPACITY DX DZ\n");
        return 2;
    }
    int renders = atoi(argv[3]);
    unsigned char *values = read_volume(argv[1]);
    /* VolPack's lookup shader indexes its colour table by a 2-byte shading field, so each
       voxel carries the value twice: as that index and as the byte the classifier reads. */
    typedef struct { unsigned short index; unsigned char value, pad; } Voxel;
    Voxel *voxels = malloc(sizeof(Voxel) * (size_t)N * N * N);
    if (!voxels) { fprintf(stderr, "volpack_render: out of memory\n"); return 1; }
    for (size_t i = 0; i < (size_t)N * N * N; i++) {
        voxels[i].index = values[i];
        voxels[i].value = values[i];
        voxels[i].pad = 0;
    }
    static float opacity[256], colour[256];
    static unsigned char image[IMG * IMG];
    for (int i = 0; i < 256; i++) {
        double v = i / 255.0;
        opacity[i] = v > 0.1 ? (float)(0.2 * (v - 0.1) / 0.9) : 0.0f;
        colour[i] = (float)i;                 /* VolPack colours are on a 0..255 scale */
    }

    vpContext *vpc = vpCreateContext();
    check(vpc, vpSetVolumeSize(vpc, N, N, N), "volume size");
    check(vpc, vpSetVoxelSize(vpc, sizeof(Voxel), 2, 1, 1), "voxel size");
    check(vpc, vpSetVoxelField(vpc, 0, 2, offsetof(Voxel, index), 255), "voxel field");
    check(vpc, vpSetVoxelField(vpc, 1, 1, offsetof(Voxel, value), 255), "voxel field");
    check(vpc, vpSetRawVoxels(vpc, voxels, (int)(sizeof(Voxel) * N * N * N), sizeof(Voxel),
                              sizeof(Voxel) * N, sizeof(Voxel) * N * N), "raw voxels");
    check(vpc, vpSetClassifierTable(vpc, 0, 1, opacity, sizeof opacity), "classifier table");
    check(vpc, vpSetLookupShader(vpc, 1, 1, 0, colour, sizeof colour, 0, NULL, 0), "shader");
    check(vpc, vpSetd(vpc, VP_MIN_VOXEL_OPACITY, atof(argv[4])), "min voxel opacity");
    check(vpc, vpSetd(vpc, VP_MAX_RAY_OPACITY, 0.99), "max ray opacity");

    /* VolPack looks along -z of eye space with +y up: turn world +z to up and +y away. */
    check(vpc, vpCurrentMatrix(vpc, VP_MODEL), "matrix");
    check(vpc, vpIdentityMatrix(vpc), "identity");
    check(vpc, vpRotate(vpc, VP_X_AXIS, -90.0), "rotate");
    check(vpc, vpTranslate(vpc, atof(argv[5]) / N, 0.0, atof(argv[6]) / N), "translate");
    check(vpc, vpCurrentMatrix(vpc, VP_PROJECT), "matrix");
    check(vpc, vpIdentityMatrix(vpc), "identity");
    check(vpc, vpWindow(vpc, VP_PARALLEL, -0.5, 0.5, -0.5, 0.5, -0.5, 0.5), "window");
    check(vpc, vpCurrentMatrix(vpc, VP_MODEL), "matrix");
    check(vpc, vpSetImage(vpc, image, IMG, IMG, IMG, VP_LUMINANCE), "image");

    double t = now();
    check(vpc, vpClassifyVolume(vpc), "classify");
    printf("classify %.6f\n", now() - t);

    double *times = malloc(sizeof(double) * (renders > 0 ? renders : 1));
    check(vpc, vpRenderClassifiedVolume(vpc), "render (cold)");
    for (int i = 0; i < renders; i++) {
        t = now();
        check(vpc, vpRenderClassifiedVolume(vpc), "render");
        times[i] = now() - t;
    }
    qsort(times, renders, sizeof(double), cmp);
    printf("render %.6f\n", renders % 2 ? times[renders / 2] : 0.5 * (times[renders / 2 - 1] + times[renders / 2]));

    FILE *out = fopen(argv[2], "wb");
    if (!out) { perror(argv[2]); return 1; }
    fprintf(out, "P5\n%d %d\n255\n", IMG, IMG);
    fwrite(image, 1, sizeof image, out);
    fclose(out);

    check(vpc, vpDestroyClassifiedVolume(vpc), "destroy classified volume");
    t = now();
    check(vpc, vpRenderRawVolume(vpc), "render raw");
    printf("render_raw %.6f\n", now() - t);
    vpDestroyContext(vpc);
    free(voxels);
    free(values);
    free(times);
    return 0;
}
