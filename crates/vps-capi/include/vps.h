/*
 * vps.h: the C ABI of the `vps` crate (Voxmap-PointShell haptic rendering).
 *
 * Build the library with `cargo build --release` (gives target/release/libvps.so) and link
 * with `cc my.c -Iinclude -Ltarget/release -lvps`. The guide is docs/C_ABI.md; the Rust side
 * is src/ffi.rs, and this header must match it exactly.
 *
 * Frames and units:
 *   - A pose maps the pointshell's frame to the voxmap's world frame:
 *       x_world = R(q) * x_pointshell + t,
 *     given as 7 doubles {tx, ty, tz, qw, qx, qy, qz} (quaternion w first; it is normalised,
 *     so it need only be finite and non-zero).
 *   - Lengths are in the world units the files were generated in.
 *   - Force is in the voxmap's world frame, in stiffness x length units; torque is in the
 *     voxmap's world frame too, about the pose's translation t (the posed pointshell origin).
 *
 * Errors: functions that can fail take `char *err, size_t err_len`. On failure they write a
 * NUL-terminated message there (cut to err_len bytes, at a UTF-8 character boundary); on
 * success they write an empty string. err may be NULL (or err_len 0) to ignore messages.
 * No function aborts or unwinds on bad input: NULL pointers are reported as errors.
 *
 * Threads: handles are read-only once opened. Any number of threads may call vps_contact on
 * the same handles at once; only closing a handle must wait until no thread uses it.
 *
 * Files: `.vxm` and `.vps` files are memory-mapped and never rewritten in place (writers
 * rename a new file over the old name). A handle keeps reading the file it opened, even
 * after the path is replaced; open a new handle to see the new file.
 */
#ifndef VPS_H
#define VPS_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Return codes of vps_contact and vps_contact_with_params. */
#define VPS_OK 0           /* success */
#define VPS_ERR_NULL 1     /* a required pointer argument is NULL */
#define VPS_ERR_POSE 2     /* the pose has a NaN/infinite component or a zero quaternion */
#define VPS_ERR_PARAM 3    /* stiffness negative or not finite, budget_us NaN, or a bad vps_contact_params field */
#define VPS_ERR_STORAGE 4  /* a file could not be read (e.g. a corrupt brick, found when a query reads it) */
#define VPS_ERR_INTERNAL 5 /* an internal error (a caught panic); please report it */

/* Penetration formulas of vps_contact_params.penetration (docs/HAPTICS.md). */
#define VPS_PENETRATION_DISTANCE 0 /* interpolated signed distance (the layers if the file has none) */
#define VPS_PENETRATION_LAYERS 1   /* the paper's layer formula, even if the file has distances */
#define VPS_PENETRATION_SHARP 2    /* the signed distance keeping convex edges and corners sharp (the layers if the file has none) */

/* An open `.vxm` voxmap with a cache of decompressed bricks. Opaque. */
typedef struct vps_voxmap vps_voxmap;

/* An open `.vps` pointshell (points, normals and sphere tree). Opaque. */
typedef struct vps_pointshell vps_pointshell;

/* The result of a contact query (vps_contact). Vectors are in the voxmap's world frame. */
typedef struct vps_contact_result {
    double force[3];              /* total force on the pointshell's object */
    double torque[3];             /* total torque about the pose's translation */
    uint64_t points_in_contact;   /* points tested that lie in a voxel with value >= 0 */
    uint64_t points_tested;       /* points whose voxel was looked up */
    uint64_t nodes_tested;        /* sphere-tree nodes tested */
    uint64_t nodes_culled;        /* nodes skipped because the voxmap proves them outside */
    uint64_t nodes_approximated;  /* nodes not refined because the budget ran out */
    uint64_t points_approximated; /* points below those nodes */
    double max_penetration;       /* largest penetration of a tested point, world units (0 if none) */
    double micros;                /* wall time of the query, microseconds */
    double force_error_bound;     /* upper bound on |force - exact force| (0 when complete) */
    double torque_error_bound;    /* upper bound on |torque - exact torque| (0 when complete) */
    int32_t complete;             /* 1: every point tested (always without a budget); 0: budget ran out */
    int32_t reserved;             /* always 0 */
    double energy;                /* energy in the contact's springs: sum of f*d/2 */
    int64_t deepest_point;        /* a point max_penetration deep (docs/C_ABI.md); -1 if none is > 0 */
} vps_contact_result;

/*
 * Open and map a `.vxm` voxmap. Returns a handle, or NULL with a message in err (missing
 * file, not a .vxm, bad checksum, unsupported version, ...). Close it with vps_voxmap_close.
 * path: NUL-terminated; its bytes are the file name.
 */
vps_voxmap *vps_voxmap_open(const char *path, char *err, size_t err_len);

/* Close a voxmap handle and unmap its file. NULL is a no-op. */
void vps_voxmap_close(vps_voxmap *voxmap);

/*
 * Open and map a `.vps` pointshell. Returns a handle, or NULL with a message in err.
 * Close it with vps_pointshell_close.
 */
vps_pointshell *vps_pointshell_open(const char *path, char *err, size_t err_len);

/* Close a pointshell handle and unmap its file. NULL is a no-op. */
void vps_pointshell_close(vps_pointshell *pointshell);

/*
 * The force and torque the voxmap exerts on the pointshell at a pose.
 *
 *   pose       7 doubles {tx, ty, tz, qw, qx, qy, qz}: pointshell frame -> voxmap world frame.
 *   stiffness  force per unit of penetration per point; finite and >= 0. The penetration is
 *              the interpolated signed distance when the voxmap file has distances (versions
 *              2 to 4, vps voxelize --distance), else the paper's layers (docs/HAPTICS.md).
 *   budget_us  <= 0: the exact answer (deterministic: the same bits in every process and on
 *              any number of threads). > 0: time-critical; stop refining the sphere tree after
 *              this many microseconds, and report the error bounds (out->complete may be 0).
 *   out        filled on success; left unchanged on failure.
 *
 * Returns VPS_OK (0), or a VPS_ERR_* code with a message in err.
 */
int vps_contact(const vps_voxmap *voxmap, const vps_pointshell *pointshell, const double pose[7], double stiffness,
                double budget_us, vps_contact_result *out, char *err, size_t err_len);

/* The parameters of vps_contact_with_params. A zeroed struct with a stiffness set asks what
 * vps_contact asks. */
typedef struct vps_contact_params {
    double stiffness;    /* as vps_contact's */
    double budget_us;    /* as vps_contact's */
    int32_t penetration; /* VPS_PENETRATION_DISTANCE (0), VPS_PENETRATION_LAYERS (1) or VPS_PENETRATION_SHARP (2) */
    int32_t reserved;    /* must be 0 */
} vps_contact_params;

/*
 * vps_contact with its parameters in a struct, which also picks the penetration formula.
 * params: a readable vps_contact_params (NULL is VPS_ERR_NULL); an unknown penetration or a
 * non-zero reserved field is VPS_ERR_PARAM.
 */
int vps_contact_with_params(const vps_voxmap *voxmap, const vps_pointshell *pointshell, const double pose[7],
                            const vps_contact_params *params, vps_contact_result *out, char *err, size_t err_len);

/*
 * The haptic loop (docs/HAPTICS.md, "The haptic loop"; docs/C_ABI.md has a device callback).
 * A simulated copy of the pointshell's object follows the device through a virtual coupling
 * and never passes through the voxmap's object; each step returns the force to render.
 * A simulation borrows its voxmap and pointshell handles: close them only after
 * vps_simulation_free. Step it from one thread at a time (the device callback's).
 */
typedef struct vps_simulation vps_simulation;

/* Parameters of vps_simulation_new; a field left 0 takes its default. */
typedef struct vps_simulation_params {
    double mass;               /* of the held object (default 1); its inertia is its shell's unless given */
    double coupling_stiffness; /* linear; default mass * (0.2 / 1 ms)^2, a 32 Hz spring */
    double coupling_damping;   /* linear; default critical for the stiffness */
    double contact_stiffness;  /* per point in contact; default the coupling's; passive up to 1000x it */
    double max_penetration;    /* deepest a point may go, voxels of the voxmap; default 0.25 */
    double step_budget_us;     /* time for a step's motion; default none (exact, same bits every run) */
    int32_t penetration;       /* VPS_PENETRATION_DISTANCE (0), VPS_PENETRATION_LAYERS (1) or VPS_PENETRATION_SHARP (2) */
    int32_t reserved;          /* must be 0 */
    double inertia[9];         /* about the centre of mass, pointshell frame, row by row (the tensor's
                                  own entries, Ixy = -integral of x*y dm); all 0: a shell over the points */
    double centre_of_mass[3];  /* pointshell frame; used when inertia is given and has_centre_of_mass is 1 */
    int32_t has_centre_of_mass; /* 1: centre_of_mass is given; 0: the shell's */
    int32_t reserved2;         /* must be 0 */
} vps_simulation_params;

/* What one step did. World frame. */
typedef struct vps_simulation_step_result {
    double pose[7];            /* the object's pose after the step, {tx, ty, tz, qw, qx, qy, qz} */
    double device_force[3];    /* the force to render on the device */
    double device_torque[3];   /* the torque to render, about the object's centre of mass */
    double contact_force[3];   /* the contact force on the object at its new pose */
    double max_penetration;    /* deepest point, world units */
    double micros;             /* wall time of the step */
    uint64_t points_in_contact;
    uint32_t queries;          /* contact queries the step ran */
    int32_t limited;           /* 1: stopped short to keep within max_penetration */
    int32_t out_of_time;       /* 1: stopped short because step_budget_us ran out */
    int32_t reserved;          /* always 0 */
    double energy_gain;        /* energy after the step less before and the device's work: <= 0 when passive */
    double energy_removed;     /* taken out by slowing the object, or backing it off, to keep passive */
    int32_t backed_off;        /* 1: backed off, at rest, to keep passive (docs/HAPTICS.md, "Passivity") */
    int32_t reserved2;         /* always 0 */
} vps_simulation_step_result;

/*
 * A simulation of pointshell's object at rest at start_pose (7 doubles, as vps_contact's
 * pose), or NULL with a message in err (a NULL argument, a bad parameter, a start pose deeper
 * than max_penetration, ...). Free it with vps_simulation_free.
 */
vps_simulation *vps_simulation_new(const vps_voxmap *voxmap, const vps_pointshell *pointshell,
                                   const vps_simulation_params *params, const double start_pose[7], char *err,
                                   size_t err_len);

/* One 1 ms step towards the device at device_pose. Returns VPS_OK and fills out, or a
 * VPS_ERR_* code with a message in err (the simulation is then unchanged). */
int vps_simulation_step(vps_simulation *simulation, const double device_pose[7], vps_simulation_step_result *out,
                        char *err, size_t err_len);

/* Free a simulation. NULL is a no-op. */
void vps_simulation_free(vps_simulation *simulation);

/* The version of the library this header belongs to. The structs' sizes can change between
 * versions (0.2.0 grew vps_contact_result, 0.3.0 vps_simulation_params and
 * vps_simulation_step_result): a caller compares it with vps_version() at
 * start-up, and does not go on when they differ. */
#define VPS_VERSION "0.3.0"

/* The library's version, e.g. "0.3.0": a static string, never to be freed. */
const char *vps_version(void);

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* VPS_H */
