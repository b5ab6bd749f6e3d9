/* A C program as an engine's plugin would be: it includes only cpvs_runtime.h and links
 * only libcpvs_runtime.so. It opens an artifact on the CPU and on a device (validation
 * on), asks both the same queries, and exits 0 when every answer agrees and the
 * validation layer reported nothing, and the bytes an engine's shader binds for the sun
 * (cpvsGetShadowsBuffer) describe its grid; it prints what went wrong otherwise.
 *   c_client FILE.cpvs X Y Z    (a point inside the artifact's scene) */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cpvs/runtime/cpvs_runtime.h"

#define COUNT 4096

int main(int argc, char** argv) {
  if (argc != 5) {
    fprintf(stderr, "usage: c_client FILE.cpvs X Y Z\n");
    return 2;
  }
  static double points[3 * COUNT], normals[3 * COUNT];
  static uint32_t onCpu[COUNT], onDevice[COUNT];
  const double x = atof(argv[2]), y = atof(argv[3]), z = atof(argv[4]);
  for (int i = 0; i < COUNT; ++i) { /* a 64 x 64 patch of points around (x, y, z), facing up */
    points[3 * i] = x + (i % 64) * 0.37 - 12;
    points[3 * i + 1] = y + (i % 7) * 3.0;
    points[3 * i + 2] = z + (i / 64) * 0.41 - 13;
    normals[3 * i] = 0, normals[3 * i + 1] = 1, normals[3 * i + 2] = 0;
  }
  CpvsShadows cpu = NULL, gpu = NULL;
  CpvsDevice device = NULL;
  CpvsDeviceDesc desc = {NULL, 1, 0};
  CpvsStatus s = cpvsOpenShadows(argv[1], NULL, 0, &cpu);
  if (s != CPVS_OK) {
    fprintf(stderr, "c_client: cpvsOpenShadows: %s: %s\n", cpvsGetStatusName(s), cpvsGetLastError());
    return 1;
  }
  if ((s = cpvsNewDevice(&desc, &device)) != CPVS_OK || (s = cpvsOpenShadows(argv[1], device, 0, &gpu)) != CPVS_OK) {
    fprintf(stderr, "c_client: device: %s: %s\n", cpvsGetStatusName(s), cpvsGetLastError());
    return 1;
  }
  int failures = 0;
  for (int pcf = 1; pcf <= 9; pcf += 2) {
    if (cpvsQueryShadows(cpu, COUNT, points, normals, pcf, onCpu) != CPVS_OK ||
        cpvsQueryShadows(gpu, COUNT, points, normals, pcf, onDevice) != CPVS_OK) {
      fprintf(stderr, "c_client: cpvsQueryShadows: %s\n", cpvsGetLastError());
      return 1;
    }
    int differ = 0, shadowed = 0;
    for (int i = 0; i < COUNT; ++i) {
      differ += onCpu[i] != onDevice[i];
      shadowed += onCpu[i] < (uint32_t)(pcf * pcf);
    }
    printf("pcf %d: %d of %d queries partly or fully shadowed, %d differ between %s and the CPU\n", pcf, shadowed,
           COUNT, differ, cpvsGetDeviceName(device));
    failures += differ != 0 || shadowed == 0 || shadowed == COUNT;
  }
  /* The sun's block: an orthographic CpvsGrid (projection at byte 184) of the words'
   * resolution (log2 at byte 188, header word 1 of the words). */
  const void* sun = NULL;
  const void* words = NULL;
  size_t sunBytes = 0, wordBytes = 0;
  if (cpvsGetShadowsBuffer(cpu, CPVS_SHADOWS_BUFFER_SUN, &sun, &sunBytes) != CPVS_OK ||
      cpvsGetShadowsBuffer(cpu, CPVS_SHADOWS_BUFFER_WORDS, &words, &wordBytes) != CPVS_OK) {
    fprintf(stderr, "c_client: cpvsGetShadowsBuffer: %s\n", cpvsGetLastError());
    return 1;
  }
  uint32_t projection = 1, log2Resolution = 0, header[2] = {0, 0};
  if (sunBytes == 224 && wordBytes >= 8) {
    memcpy(&projection, (const char*)sun + 184, 4);
    memcpy(&log2Resolution, (const char*)sun + 188, 4);
    memcpy(header, words, 8);
  }
  printf("the sun's block: %zu bytes, projection %u, 2^%u texels a side; %zu bytes of words\n", sunBytes, projection,
         log2Resolution, wordBytes);
  failures += sunBytes != 224 || projection != 0 || log2Resolution != header[1] || log2Resolution == 0;
  if (cpvsGetValidationMessageCount(device) != 0) {
    fprintf(stderr, "c_client: the validation layer reported %zu messages\n", cpvsGetValidationMessageCount(device));
    ++failures;
  }
  cpvsReleaseShadows(gpu);
  cpvsReleaseShadows(cpu);
  cpvsReleaseDevice(device);
  return failures == 0 ? 0 : 1;
}
