/*
 * simulate: the haptic loop through the C ABI, the way a device driver's 1 kHz callback
 * (CHAI3D, OpenHaptics' HD scheduler, ...) would run it; docs/C_ABI.md shows the callback.
 *
 *   simulate VXM VPS POSES
 *
 * POSES: one device pose per line, "tx ty tz qw qx qy qz", 1 ms apart. The object starts at
 * the first. For each pose one line is printed:
 *
 *   step fx fy fz tx ty tz points_in_contact limited energy_gain backed_off
 *
 * the force to render, the object's position after the step, its energy balance, with the
 * doubles as %.17g (they read back to the same bits). Exit status: 0 all good, 1 a step failed, 2 bad usage or files.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "vps.h"

/* What the callback shares with the rest of the application. */
typedef struct {
    vps_simulation *sim;
    double force[3];  /* to render on the device */
    double torque[3];
    int failed;       /* a step failed: render nothing from now on */
    char err[256];
    vps_simulation_step_result last;
} haptic_state;

/* Called by the device driver every millisecond with the device's pose. Never blocks, never
 * allocates: one vps_simulation_step, then the force goes to the device. */
static void haptic_callback(haptic_state *st, const double device_pose[7]) {
    if (st->failed) return;
    if (vps_simulation_step(st->sim, device_pose, &st->last, st->err, sizeof st->err) != VPS_OK) {
        st->failed = 1;
        memset(st->force, 0, sizeof st->force);
        memset(st->torque, 0, sizeof st->torque);
        return;
    }
    memcpy(st->force, st->last.device_force, sizeof st->force);
    memcpy(st->torque, st->last.device_torque, sizeof st->torque);
    /* here: hdSetDoublev(HD_CURRENT_FORCE, st->force) or the driver's equivalent */
}

int main(int argc, char **argv) {
    if (argc != 4) {
        fprintf(stderr, "usage: simulate VXM VPS POSES\n");
        return 2;
    }
    /* The structs below are this header's: the library must be the same version. */
    if (strcmp(vps_version(), VPS_VERSION) != 0) {
        fprintf(stderr, "simulate: built against vps %s, running with %s\n", VPS_VERSION, vps_version());
        return 2;
    }
    FILE *in = fopen(argv[3], "r");
    if (!in) {
        fprintf(stderr, "simulate: cannot open %s\n", argv[3]);
        return 2;
    }
    size_t n = 0, cap = 64;
    double(*poses)[7] = malloc(cap * sizeof *poses);
    char line[1024];
    while (poses && fgets(line, sizeof line, in)) {
        if (line[0] == '#' || line[0] == '\n') continue;
        if (n == cap) {
            cap *= 2;
            double(*more)[7] = realloc(poses, cap * sizeof *poses);
            if (!more) break;
            poses = more;
        }
        double *p = poses[n];
        if (sscanf(line, "%lf %lf %lf %lf %lf %lf %lf", &p[0], &p[1], &p[2], &p[3], &p[4], &p[5], &p[6]) != 7) {
            fprintf(stderr, "simulate: a pose is 7 numbers: %s", line);
            return 2;
        }
        n++;
    }
    fclose(in);
    if (!poses || n == 0) {
        fprintf(stderr, "simulate: no poses\n");
        return 2;
    }

    char err[256];
    vps_voxmap *vm = vps_voxmap_open(argv[1], err, sizeof err);
    if (!vm) {
        fprintf(stderr, "simulate: %s\n", err);
        return 2;
    }
    vps_pointshell *ps = vps_pointshell_open(argv[2], err, sizeof err);
    if (!ps) {
        fprintf(stderr, "simulate: %s\n", err);
        vps_voxmap_close(vm);
        return 2;
    }
    vps_simulation_params params = {0}; /* every default: mass 1, 32 Hz coupling, 1/4 voxel */
    haptic_state st = {0};
    st.sim = vps_simulation_new(vm, ps, &params, poses[0], err, sizeof err);
    if (!st.sim) {
        fprintf(stderr, "simulate: %s\n", err);
        vps_pointshell_close(ps);
        vps_voxmap_close(vm);
        return 2;
    }

    /* The device driver's loop, here a recorded trajectory. */
    for (size_t i = 0; i < n && !st.failed; i++) {
        haptic_callback(&st, poses[i]);
        if (st.failed) break;
        const vps_simulation_step_result *r = &st.last;
        printf("%zu %.17g %.17g %.17g %.17g %.17g %.17g %llu %d %.17g %d\n", i, st.force[0], st.force[1],
               st.force[2], r->pose[0], r->pose[1], r->pose[2], (unsigned long long)r->points_in_contact,
               (int)r->limited, r->energy_gain, (int)r->backed_off);
    }
    if (st.failed) fprintf(stderr, "simulate: %s\n", st.err);

    /* The simulation first: it borrows the handles. */
    vps_simulation_free(st.sim);
    vps_pointshell_close(ps);
    vps_voxmap_close(vm);
    free(poses);
    return st.failed;
}
