/*
 * errors: the edge cases of the C ABI of libvps, checked from C.
 *
 *   errors VXM VPS
 *
 * VXM and VPS are valid files whose pointshell, at the identity pose, touches the voxmap.
 * Checks NULL arguments, bad poses and parameters, message buffers (truncation, err_len 0,
 * err NULL, cleared on success), that `out` is untouched on failure, the version string and
 * the time-critical mode. Prints "ok N checks" and exits 0, or prints each failure and exits 1.
 */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#include "vps.h"

static int checks, failures;

#define CHECK(cond)                                                                                                    \
    do {                                                                                                               \
        checks++;                                                                                                      \
        if (!(cond)) {                                                                                                 \
            failures++;                                                                                                \
            printf("FAIL line %d: %s\n", __LINE__, #cond);                                                             \
        }                                                                                                              \
    } while (0)

/* Whether out still holds the sentinel bytes 0xAB. */
static int untouched(const vps_contact_result *out) {
    const unsigned char *b = (const unsigned char *)out;
    for (size_t i = 0; i < sizeof *out; i++)
        if (b[i] != 0xAB) return 0;
    return 1;
}

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: errors VXM VPS\n");
        return 2;
    }
    char err[256];

    /* What this header says, for the caller to compare with the library's side. */
    printf("layout %zu %zu %zu %zu %zu %zu %zu %zu %zu %zu %zu %zu %zu %zu %zu %zu %zu\n", sizeof(vps_contact_result),
           offsetof(vps_contact_result, force), offsetof(vps_contact_result, torque),
           offsetof(vps_contact_result, points_in_contact), offsetof(vps_contact_result, points_tested),
           offsetof(vps_contact_result, nodes_tested), offsetof(vps_contact_result, nodes_culled),
           offsetof(vps_contact_result, nodes_approximated), offsetof(vps_contact_result, points_approximated),
           offsetof(vps_contact_result, max_penetration), offsetof(vps_contact_result, micros),
           offsetof(vps_contact_result, force_error_bound), offsetof(vps_contact_result, torque_error_bound),
           offsetof(vps_contact_result, complete), offsetof(vps_contact_result, reserved),
           offsetof(vps_contact_result, energy), offsetof(vps_contact_result, deepest_point));
    printf("codes %d %d %d %d %d %d\n", VPS_OK, VPS_ERR_NULL, VPS_ERR_POSE, VPS_ERR_PARAM, VPS_ERR_STORAGE,
           VPS_ERR_INTERNAL);
    printf("params %zu %zu %zu %zu %zu %d %d %d\n", sizeof(vps_contact_params), offsetof(vps_contact_params, stiffness),
           offsetof(vps_contact_params, budget_us), offsetof(vps_contact_params, penetration),
           offsetof(vps_contact_params, reserved), VPS_PENETRATION_DISTANCE, VPS_PENETRATION_LAYERS,
           VPS_PENETRATION_SHARP);
    printf("simulation %zu %zu %zu %zu %zu %zu %zu %zu %zu %zu\n", sizeof(vps_simulation_params),
           offsetof(vps_simulation_params, max_penetration), offsetof(vps_simulation_params, step_budget_us),
           offsetof(vps_simulation_params, penetration),
           sizeof(vps_simulation_step_result), offsetof(vps_simulation_step_result, device_force),
           offsetof(vps_simulation_step_result, contact_force), offsetof(vps_simulation_step_result, points_in_contact),
           offsetof(vps_simulation_step_result, queries), offsetof(vps_simulation_step_result, out_of_time));
    printf("version %s\n", vps_version());
    printf("header_version %s\n", VPS_VERSION);

    /* Version. */
    const char *v = vps_version();
    CHECK(v != NULL && strlen(v) > 0);
    CHECK(vps_version() == v);

    /* Opening. */
    memset(err, 'x', sizeof err);
    CHECK(vps_voxmap_open(NULL, err, sizeof err) == NULL);
    CHECK(strcmp(err, "path is NULL") == 0);
    CHECK(vps_pointshell_open("", err, sizeof err) == NULL);
    CHECK(strcmp(err, "path is empty") == 0);
    CHECK(vps_voxmap_open("/nonexistent/dir/a.vxm", NULL, 0) == NULL); /* no buffer: fine */
    memset(err, 'x', sizeof err);
    CHECK(vps_voxmap_open("/nonexistent/dir/a.vxm", err, 8) == NULL); /* cut to 7 bytes + NUL */
    CHECK(strlen(err) == 7 && err[8] == 'x');
    memset(err, 'x', sizeof err);
    CHECK(vps_pointshell_open("/nonexistent/dir/a.vps", err, 0) == NULL); /* err_len 0: untouched */
    CHECK(err[0] == 'x');
    /* The wrong kind of file. */
    CHECK(vps_voxmap_open(argv[2], err, sizeof err) == NULL);
    CHECK(strstr(err, "not a .vxm") != NULL);
    CHECK(vps_pointshell_open(argv[1], err, sizeof err) == NULL);
    CHECK(strstr(err, "not a") != NULL);

    /* Closing NULL. */
    vps_voxmap_close(NULL);
    vps_pointshell_close(NULL);

    memset(err, 'x', sizeof err);
    vps_voxmap *vm = vps_voxmap_open(argv[1], err, sizeof err);
    CHECK(vm != NULL);
    CHECK(err[0] == '\0'); /* success clears the message */
    vps_pointshell *ps = vps_pointshell_open(argv[2], NULL, 0);
    CHECK(ps != NULL);
    if (!vm || !ps) {
        printf("cannot open the files: %s\n", err);
        return 1;
    }

    const double id[7] = {0, 0, 0, 1, 0, 0, 0};
    vps_contact_result out;

    /* NULL arguments. */
    memset(&out, 0xAB, sizeof out);
    CHECK(vps_contact(NULL, ps, id, 1, 0, &out, err, sizeof err) == VPS_ERR_NULL);
    CHECK(strcmp(err, "voxmap is NULL") == 0);
    CHECK(vps_contact(vm, NULL, id, 1, 0, &out, err, sizeof err) == VPS_ERR_NULL);
    CHECK(strcmp(err, "pointshell is NULL") == 0);
    CHECK(vps_contact(vm, ps, NULL, 1, 0, &out, err, sizeof err) == VPS_ERR_NULL);
    CHECK(strcmp(err, "pose is NULL") == 0);
    CHECK(vps_contact(vm, ps, id, 1, 0, NULL, err, sizeof err) == VPS_ERR_NULL);
    CHECK(strcmp(err, "out is NULL") == 0);
    CHECK(vps_contact(vm, ps, id, 1, 0, NULL, NULL, 0) == VPS_ERR_NULL);

    /* Bad poses. */
    const double zero_q[7] = {0, 0, 0, 0, 0, 0, 0};
    const double nan_t[7] = {NAN, 0, 0, 1, 0, 0, 0};
    const double inf_q[7] = {0, 0, 0, 1, INFINITY, 0, 0};
    CHECK(vps_contact(vm, ps, zero_q, 1, 0, &out, err, sizeof err) == VPS_ERR_POSE);
    CHECK(strstr(err, "quaternion") != NULL);
    CHECK(vps_contact(vm, ps, nan_t, 1, 0, &out, err, sizeof err) == VPS_ERR_POSE);
    CHECK(strstr(err, "non-finite") != NULL);
    CHECK(vps_contact(vm, ps, inf_q, 1, 0, &out, err, sizeof err) == VPS_ERR_POSE);

    /* Bad parameters. */
    CHECK(vps_contact(vm, ps, id, -1, 0, &out, err, sizeof err) == VPS_ERR_PARAM);
    CHECK(strstr(err, "stiffness") != NULL);
    CHECK(vps_contact(vm, ps, id, NAN, 0, &out, err, sizeof err) == VPS_ERR_PARAM);
    CHECK(vps_contact(vm, ps, id, INFINITY, 0, &out, err, sizeof err) == VPS_ERR_PARAM);
    CHECK(vps_contact(vm, ps, id, 1, NAN, &out, err, sizeof err) == VPS_ERR_PARAM);
    CHECK(strstr(err, "budget") != NULL);
    CHECK(untouched(&out)); /* failures leave out alone */

    /* Success: exact, with and without a message buffer; a non-unit quaternion is normalised. */
    vps_contact_result a, b, c;
    memset(err, 'x', sizeof err);
    CHECK(vps_contact(vm, ps, id, 2, 0, &a, err, sizeof err) == VPS_OK);
    CHECK(err[0] == '\0');
    CHECK(a.complete == 1 && a.reserved == 0);
    CHECK(a.points_in_contact > 0 && a.points_tested >= a.points_in_contact);
    CHECK(a.max_penetration > 0 && a.force_error_bound == 0 && a.torque_error_bound == 0);
    CHECK(a.nodes_approximated == 0 && a.points_approximated == 0);
    const double id2[7] = {0, 0, 0, 3, 0, 0, 0};
    CHECK(vps_contact(vm, ps, id2, 2, -5, &b, NULL, 0) == VPS_OK);
    CHECK(memcmp(a.force, b.force, sizeof a.force) == 0 && memcmp(a.torque, b.torque, sizeof a.torque) == 0);
    /* Stiffness scales the force. */
    CHECK(vps_contact(vm, ps, id, 0, 0, &c, err, sizeof err) == VPS_OK);
    CHECK(c.force[0] == 0 && c.force[1] == 0 && c.force[2] == 0 && c.points_in_contact == a.points_in_contact);

    /* The params form: zeroed fields but the stiffness are vps_contact's defaults; the layer
     * penetration is another formula on this (version 2) file; bad choices are refused. */
    vps_contact_params params = {0};
    params.stiffness = 2;
    CHECK(vps_contact_with_params(vm, ps, id, &params, &b, err, sizeof err) == VPS_OK);
    CHECK(memcmp(a.force, b.force, sizeof a.force) == 0 && b.points_in_contact == a.points_in_contact);
    params.penetration = VPS_PENETRATION_LAYERS;
    CHECK(vps_contact_with_params(vm, ps, id, &params, &c, err, sizeof err) == VPS_OK);
    CHECK(c.points_in_contact == a.points_in_contact && memcmp(a.force, c.force, sizeof a.force) != 0);
    CHECK(vps_contact_with_params(vm, ps, id, NULL, &c, err, sizeof err) == VPS_ERR_NULL);
    CHECK(strcmp(err, "params is NULL") == 0);
    params.penetration = 3;
    memset(&out, 0xAB, sizeof out);
    CHECK(vps_contact_with_params(vm, ps, id, &params, &out, err, sizeof err) == VPS_ERR_PARAM);
    CHECK(strstr(err, "penetration 3") != NULL);
    params.penetration = VPS_PENETRATION_DISTANCE;
    params.reserved = 1;
    CHECK(vps_contact_with_params(vm, ps, id, &params, &out, err, sizeof err) == VPS_ERR_PARAM);
    CHECK(strstr(err, "reserved") != NULL);
    CHECK(untouched(&out));

    /* The haptic loop's errors: NULLs, bad parameters, a start too deep; free(NULL) is fine. */
    vps_simulation_params sp = {0};
    const double far_pose[7] = {10, 10, 10, 1, 0, 0, 0};
    CHECK(vps_simulation_new(vm, ps, NULL, far_pose, err, sizeof err) == NULL);
    CHECK(strcmp(err, "params is NULL") == 0);
    CHECK(vps_simulation_new(NULL, ps, &sp, far_pose, err, sizeof err) == NULL);
    CHECK(strcmp(err, "voxmap is NULL") == 0);
    sp.mass = -1;
    CHECK(vps_simulation_new(vm, ps, &sp, far_pose, err, sizeof err) == NULL);
    CHECK(strstr(err, "mass") != NULL);
    sp.mass = 0;
    sp.penetration = 7;
    CHECK(vps_simulation_new(vm, ps, &sp, far_pose, err, sizeof err) == NULL);
    CHECK(strstr(err, "penetration 7") != NULL);
    sp.penetration = 0;
    CHECK(vps_simulation_new(vm, ps, &sp, id, err, sizeof err) == NULL); /* starts deep inside */
    CHECK(strstr(err, "deep") != NULL);
    vps_simulation *sim = vps_simulation_new(vm, ps, &sp, far_pose, err, sizeof err);
    CHECK(sim != NULL && err[0] == '\0');
    vps_simulation_step_result sr;
    CHECK(vps_simulation_step(NULL, far_pose, &sr, err, sizeof err) == VPS_ERR_NULL);
    CHECK(strcmp(err, "simulation is NULL") == 0);
    CHECK(vps_simulation_step(sim, zero_q, &sr, err, sizeof err) == VPS_ERR_POSE);
    CHECK(vps_simulation_step(sim, far_pose, &sr, err, sizeof err) == VPS_OK);
    CHECK(sr.points_in_contact == 0 && sr.limited == 0 && sr.device_force[0] == 0);
    vps_simulation_free(sim);
    vps_simulation_free(NULL);

    /* Time-critical: a generous budget is exact; a tiny one still answers, with bounds. */
    CHECK(vps_contact(vm, ps, id, 2, 1e9, &b, err, sizeof err) == VPS_OK);
    CHECK(b.complete == 1 && b.points_in_contact == a.points_in_contact);
    CHECK(vps_contact(vm, ps, id, 2, INFINITY, &b, err, sizeof err) == VPS_OK);
    CHECK(b.complete == 1);
    CHECK(vps_contact(vm, ps, id, 2, 1e-3, &b, err, sizeof err) == VPS_OK);
    CHECK(b.complete == 0 || b.complete == 1);
    CHECK(b.force_error_bound >= 0 && b.torque_error_bound >= 0);
    CHECK(b.complete == 1 || b.nodes_approximated > 0);

    vps_pointshell_close(ps);
    vps_voxmap_close(vm);
    if (failures) {
        printf("%d of %d checks failed\n", failures, checks);
        return 1;
    }
    printf("ok %d checks\n", checks);
    return 0;
}
