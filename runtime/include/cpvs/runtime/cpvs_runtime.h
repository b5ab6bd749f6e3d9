/* cpvs_runtime's C API: opaque handles, explicit status codes, for engines whose plugin
 * interfaces are C. Every function returns a CpvsStatus (or a value that cannot fail);
 * on failure cpvsGetLastError() describes it (per thread, valid until the thread's next
 * call). Handles are not thread-safe: one thread at a time per handle. A CpvsDevice must
 * outlive the CpvsShadows and CpvsLights made on it. */
#ifndef CPVS_RUNTIME_H
#define CPVS_RUNTIME_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum CpvsStatus {
  CPVS_OK = 0,
  CPVS_ERROR_INVALID_ARGUMENT = 1, /* a null, out-of-range or inconsistent argument */
  CPVS_ERROR_FILE = 2,             /* a file cannot be read or written */
  CPVS_ERROR_CORRUPT_ARTIFACT = 3, /* not a valid .cpvs or .dmh: truncated, damaged, foreign */
  CPVS_ERROR_NO_VULKAN = 4,        /* no Vulkan loader, or no driver behind it */
  CPVS_ERROR_NO_DEVICE = 5,        /* no device, none selected, or none with 64-bit floats */
  CPVS_ERROR_DEVICE_LOST = 6,      /* the device stopped answering */
  CPVS_ERROR_OUT_OF_MEMORY = 7,
  CPVS_ERROR_FARM = 8,             /* the farm refused the request or could not be reached */
  CPVS_ERROR_INTERNAL = 9
} CpvsStatus;

typedef struct CpvsDevice_T* CpvsDevice;
typedef struct CpvsShadows_T* CpvsShadows;
typedef struct CpvsLights_T* CpvsLights;

/* How cpvsNewDevice picks a device; a null pointer means all defaults. */
typedef struct CpvsDeviceDesc {
  const char* select;       /* a device whose name contains this; NULL: CPVS_DEVICE, else the best */
  int validation;           /* nonzero: the Khronos validation layer, its reports collected */
  uint64_t maxBindingBytes; /* 0: the device's maxStorageBufferRange */
} CpvsDeviceDesc;

/* cpvsOpenShadows flags. */
#define CPVS_FALLBACK_CPU 1u /* answer on the CPU when the device cannot (none, lost) */

/* A headless device the library creates: the first discrete GPU, then integrated, then
 * virtual, then a CPU device (lavapipe). */
CpvsStatus cpvsNewDevice(const CpvsDeviceDesc* desc, CpvsDevice* device);
/* The application's own device (created with shaderFloat64, queueFamily with compute).
 * getInstanceProcAddr: its PFN_vkGetInstanceProcAddr, or NULL for libvulkan.so.1's. */
CpvsStatus cpvsNewDeviceFromVulkan(void* instance, void* physicalDevice, void* vkDevice, uint32_t queueFamily,
                                   void* getInstanceProcAddr, CpvsDevice* device);
void cpvsReleaseDevice(CpvsDevice device);
/* The device's name; "" for NULL. Valid while the device lives. */
const char* cpvsGetDeviceName(CpvsDevice device);
/* How many messages the validation layer reported (errors and warnings). */
size_t cpvsGetValidationMessageCount(CpvsDevice device);
/* Tests only: every later submission on the device fails as a lost device does. */
void cpvsSimulateDeviceLossForTests(CpvsDevice device);

/* Opens a .cpvs or a .dmh (`cpvs bake --format dagmh`) and uploads it to `device` (NULL:
 * lookups on the CPU), either kind answering the same calls. With
 * CPVS_FALLBACK_CPU, a failed upload leaves the shadows on the CPU instead of failing. */
CpvsStatus cpvsOpenShadows(const char* path, CpvsDevice device, uint32_t flags, CpvsShadows* shadows);
/* Fetches a finished farm job's artifact into cacheDir (kept under its content hash;
 * answered from there when fetched before) and writes its path into pathOut. */
CpvsStatus cpvsFetchShadows(const char* address, const char* tokenOrNull, const char* caFileOrNull, const char* jobId,
                            const char* cacheDir, char* pathOut, size_t pathCapacity);
void cpvsReleaseShadows(CpvsShadows shadows);
/* 1 when lookups run on the device, 0 on the CPU. */
int cpvsShadowsOnDevice(CpvsShadows shadows);
/* What the artifact holds: a CPVS, or a DAG-MH, whose words an engine's shader reads with
 * CPVS_DAG_MH defined before including cpvs_shadow.glsl. CPVS for NULL. */
typedef enum CpvsShadowsKind { CPVS_SHADOWS_CPVS = 0, CPVS_SHADOWS_DAG_MH = 1 } CpvsShadowsKind;
CpvsShadowsKind cpvsGetShadowsKind(CpvsShadows shadows);

/* count queries: points (3 doubles each, world space), normals (3 each, or NULL: no
 * offset), filter width pcf (odd, 1 to 9). litTexels[i] receives how many of the
 * pcf x pcf texels are lit (for pcf 1: 1 lit, 0 shadowed), as the CPU reference answers. */
CpvsStatus cpvsQueryShadows(CpvsShadows shadows, size_t count, const double* points, const double* normals, int pcf,
                            uint32_t* litTexels);

/* The buffers an engine's own shader binds for cpvs_shadow.glsl's sun lookups, as bytes
 * to upload: the uniform block CpvsSun (224 bytes: the grid's one record, CpvsGrid, as a
 * light bundle's grids have it, then the log2 of the words per word buffer, 0 here: an
 * engine that splits the words across buffers, CPVS_WORD_BUFFERS > 1, writes its own at
 * byte 208) and the words (CpvsWords: a CPVS's, or a DAG-MH's, cpvsGetShadowsKind). Valid
 * while the CpvsShadows lives. */
typedef enum CpvsShadowsBuffer {
  CPVS_SHADOWS_BUFFER_SUN = 0,
  CPVS_SHADOWS_BUFFER_WORDS = 1,
  CPVS_SHADOWS_BUFFER_CASTERS = 2, /* CpvsCasters (CPVS_CASTERS) of the casters last set; 0 bytes: none */
  CPVS_SHADOWS_BUFFER_TRANSLUCENT = 3,  /* CpvsTranslucent (CPVS_TRANSLUCENT): the artifact's translucent casters'
                                           tree (its root 0 when it has none) */
  CPVS_SHADOWS_BUFFER_TRANSMITTANCE = 4 /* CpvsTransmittances: their RGB transmittance, 3 floats a frustum */
} CpvsShadowsBuffer;
CpvsStatus cpvsGetShadowsBuffer(CpvsShadows shadows, CpvsShadowsBuffer which, const void** data, size_t* bytes);

/* --- translucent casters: glass, water and leaves on cards the bake left out of the CPVS
 * and stored beside it as a TOP tree (seed 003 §3.4) */

/* 1 when the artifact carries translucent casters, 0 otherwise. */
int cpvsShadowsHaveTranslucentCasters(CpvsShadows shadows);
/* count queries as cpvsQueryShadows': rgb[3 i .. 3 i + 2] receives the sun light let
 * through the translucent casters at point i moved one texel along its normal (1, 1, 1
 * where none is in the way, and everywhere without them): multiply the visibility by it.
 * On a device, deeper walks than its 64-entry stack are answered on the CPU. */
CpvsStatus cpvsQueryTransmittance(CpvsShadows shadows, size_t count, const double* points, const double* normals,
                                  float* rgb);

/* --- dynamic casters: what moves (characters, vehicles, doors) casts exact sun shadows
 * on the baked world and on itself, by partitioned shadow volumes (a TOP tree, seed 003) */
typedef struct CpvsCasterMesh {
  const double* positions; /* 3 doubles a vertex, in the mesh's own space */
  size_t vertexCount;
  const uint32_t* indices; /* 3 a triangle */
  size_t triangleCount;
  const uint8_t* closed;   /* NULL, or 1 a triangle: part of a closed, outward-facing mesh (its faces towards
                              the sun are left out: the far side casts the same shadow) */
  double transform[12];    /* where it is this frame: world = [M | t] (p, 1), row-major 3x4 */
} CpvsCasterMesh;
/* This frame's dynamic casters (meshCount 0: none). Their shadow frusta are made on the
 * CPU and, on a device, inserted into their tree there (on the CPU otherwise); every
 * later cpvsQueryShadows answers the baked shadows times theirs: 0 lit
 * texels where a caster shadows the point, asked normalOffset along its normal (< 0: one
 * texel of the artifact's grid). On a device, the points whose walk needs more than the
 * shader's 32-entry stack are answered on the CPU. */
CpvsStatus cpvsSetDynamicCasters(CpvsShadows shadows, const CpvsCasterMesh* meshes, size_t meshCount, double normalOffset);

/* --- local lights: a light bundle (.cpvs format 4, `cpvs bake --spot/--point/--lights`) */

/* Opens a light bundle and uploads it to `device` (NULL: lookups on the CPU); flags as
 * cpvsOpenShadows. A CpvsDevice must outlive the CpvsLights made on it. */
CpvsStatus cpvsOpenLights(const char* path, CpvsDevice device, uint32_t flags, CpvsLights* lights);
void cpvsReleaseLights(CpvsLights lights);
/* 1 when lookups run on the device, 0 on the CPU. */
int cpvsLightsOnDevice(CpvsLights lights);
/* How many lights the bundle holds; 0 for NULL. */
size_t cpvsGetLightCount(CpvsLights lights);

/* A light as the bundle records it, for shading. */
typedef struct CpvsLightInfo {
  uint32_t kind;         /* 0 spot, 1 point (six grids, a cube) */
  uint32_t gridCount;
  double position[3];
  double direction[3];   /* a spot light's axis, unit length; zero for a point light */
  double coneDeg;        /* a spot light's half-angle */
  double range;          /* no light beyond this distance along its axis (its grids' far) */
  double colour[3];      /* linear RGB */
  double intensity;
  const char* name;      /* valid while the CpvsLights lives */
} CpvsLightInfo;
CpvsStatus cpvsGetLightInfo(CpvsLights lights, size_t light, CpvsLightInfo* info);

/* count queries, query i of light lightOfQuery[i] (lightCount 1: lightOfQuery[0] for
 * all; otherwise lightCount must be count): points, normals and pcf as cpvsQueryShadows.
 * litTexels[i] receives the lit texels of that light's footprint (0 outside its cone,
 * beyond its range, behind it), as the CPU reference answers. */
CpvsStatus cpvsQueryLights(CpvsLights lights, size_t count, const uint32_t* lightOfQuery, size_t lightCount,
                           const double* points, const double* normals, int pcf, uint32_t* litTexels);

/* A bundle's area lights (cpvs bake --area-light), 0-based: how many, and area light
 * a's VPLs, the lights firstVpl .. firstVpl + vplCount - 1 (cpvs_shadow.glsl's
 * cpvsSoftVisibility takes firstVpl). */
size_t cpvsGetAreaLightCount(CpvsLights lights);
CpvsStatus cpvsGetAreaLight(CpvsLights lights, size_t area, uint32_t* firstVpl, uint32_t* vplCount);

/* count queries, query i of area light areaOfQuery[i] (areaCount 1: areaOfQuery[0] for
 * all; otherwise areaCount must be count): points and normals as cpvsQueryShadows (a
 * null normals: no receiver cosine). visibility[i] receives its soft visibility in
 * [0, 1], the VPLs' bilinear visibilities weighted by cos * cos / d^2, as the CPU
 * reference answers to the bit. */
CpvsStatus cpvsQuerySoftShadows(CpvsLights lights, size_t count, const uint32_t* areaOfQuery, size_t areaCount,
                                const double* points, const double* normals, float* visibility);

/* The buffers an engine's own shader binds for cpvs_shadow.glsl with CPVS_LIGHTS, as
 * bytes to upload: the shared pool's words (CpvsLightWords), CpvsLights, CpvsGrids
 * and CpvsSliceBoundaries. CpvsGrids begins with the log2 of the words per pool
 * buffer, 0 here: an engine that splits the pool across buffers (CPVS_LIGHT_WORD_BUFFERS
 * > 1) writes its own there. Valid while the CpvsLights lives. */
typedef enum CpvsLightBuffer {
  CPVS_LIGHT_BUFFER_WORDS = 0,
  CPVS_LIGHT_BUFFER_LIGHTS = 1,
  CPVS_LIGHT_BUFFER_GRIDS = 2,
  CPVS_LIGHT_BUFFER_BOUNDARIES = 3,
  CPVS_LIGHT_BUFFER_CASTER_TREES = 4, /* CpvsLightCasters (CPVS_LIGHT_CASTERS) of the casters last set; 0 bytes: none */
  CPVS_LIGHT_BUFFER_CASTER_NODES = 5  /* CpvsLightCasterNodes */
} CpvsLightBuffer;
CpvsStatus cpvsGetLightBuffer(CpvsLights lights, CpvsLightBuffer which, const void** data, size_t* bytes);
/* This frame's dynamic casters under the bundle's lights (meshCount 0: none), as
 * cpvsSetDynamicCasters for the sun: a tree of each spot or point light whose range the
 * casters enter, built on the CPU; every later cpvsQueryLights answers 0 lit texels where
 * a caster shadows the point from that light (asked normalOffset along its normal; < 0:
 * per light one texel of its grid at its range). Area lights' soft lookups ignore them. */
CpvsStatus cpvsSetLightCasters(CpvsLights lights, const CpvsCasterMesh* meshes, size_t meshCount, double normalOffset);

/* The message of this thread's last failure ("" when none). */
const char* cpvsGetLastError(void);
/* "ok", "no-device", ... */
const char* cpvsGetStatusName(CpvsStatus status);

#ifdef __cplusplus
}
#endif

#endif /* CPVS_RUNTIME_H */
