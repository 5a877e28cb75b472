/*
 * contact: query a voxmap and a pointshell through the C ABI of libvps, one pose per line.
 *
 *   contact [-t THREADS] [-b BUDGET_US] [-l | -s] VXM VPS STIFFNESS [POSES]
 *
 * -l asks for the layer penetration, -s for the sharp one (vps_contact_with_params); without
 * either, vps_contact's default.
 *
 * Poses are read from the file POSES, or from stdin when it is absent or "-": one pose per
 * line, 7 numbers "tx ty tz qw qx qy qz" separated by spaces, tabs or commas. Blank lines and
 * lines starting with '#' are skipped. The line "reopen" closes both handles and opens the
 * files again (printing "reopened"), so a long-running reader can pick up replaced files.
 *
 * For each pose one line is printed, and flushed at once (so a parent can talk to this
 * program through pipes):
 *
 *   ok fx fy fz tx ty tz points_in_contact points_tested nodes_tested nodes_culled max_penetration complete
 *      energy deepest_point
 *
 * with the doubles printed as %.17g, which reads back to the same bits; or, when the query
 * fails, "error CODE MESSAGE" (and the exit status will be 1).
 *
 * With -t THREADS > 1 all poses are read first, then THREADS threads query every pose on the
 * same two handles; the program checks that all threads got the same bits and prints the
 * answers once. Exit status: 0 all good, 1 a query failed (or threads disagreed), 2 bad usage
 * or a file could not be opened (message on stderr).
 */
#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "vps.h"

#define ERR_LEN 1024

typedef struct {
    double pose[7];
    int code;
    vps_contact_result c;
    char err[ERR_LEN];
} query;

static vps_voxmap *voxmap;
static vps_pointshell *shell;
static const char *vxm_path, *vps_path;
static double stiffness, budget_us;
/* -1: vps_contact's default; else the penetration asked for with vps_contact_with_params. */
static int32_t penetration = -1;

static void open_files(void) {
    char err[ERR_LEN];
    voxmap = vps_voxmap_open(vxm_path, err, sizeof err);
    if (!voxmap) {
        fprintf(stderr, "contact: cannot open voxmap: %s\n", err);
        exit(2);
    }
    shell = vps_pointshell_open(vps_path, err, sizeof err);
    if (!shell) {
        fprintf(stderr, "contact: cannot open pointshell: %s\n", err);
        vps_voxmap_close(voxmap);
        exit(2);
    }
}

static void close_files(void) {
    vps_pointshell_close(shell);
    vps_voxmap_close(voxmap);
    shell = NULL;
    voxmap = NULL;
}

/* Parse 7 numbers; returns the count found (7 on success, 8 if there are more). */
static int parse_pose(const char *line, double pose[7]) {
    int n = 0;
    const char *p = line;
    for (;;) {
        while (*p == ' ' || *p == '\t' || *p == ',' || *p == '\r' || *p == '\n') p++;
        if (!*p) break;
        char *end;
        double v = strtod(p, &end);
        if (end == p) return -1;
        if (n == 7) return 8;
        pose[n++] = v;
        p = end;
    }
    return n;
}

static void run(query *q) {
    if (penetration >= 0) {
        vps_contact_params params = {0};
        params.stiffness = stiffness;
        params.budget_us = budget_us;
        params.penetration = penetration;
        q->code = vps_contact_with_params(voxmap, shell, q->pose, &params, &q->c, q->err, sizeof q->err);
    } else {
        q->code = vps_contact(voxmap, shell, q->pose, stiffness, budget_us, &q->c, q->err, sizeof q->err);
    }
}

/* Print one answer; returns 1 when it is an error. */
static int print(const query *q) {
    if (q->code != VPS_OK) {
        printf("error %d %s\n", q->code, q->err);
    } else {
        const vps_contact_result *c = &q->c;
        printf("ok %.17g %.17g %.17g %.17g %.17g %.17g %llu %llu %llu %llu %.17g %d %.17g %lld\n", c->force[0], c->force[1],
               c->force[2], c->torque[0], c->torque[1], c->torque[2], (unsigned long long)c->points_in_contact,
               (unsigned long long)c->points_tested, (unsigned long long)c->nodes_tested,
               (unsigned long long)c->nodes_culled, c->max_penetration, (int)c->complete, c->energy,
               (long long)c->deepest_point);
    }
    fflush(stdout);
    return q->code != VPS_OK;
}

/* Everything but the wall time. */
static int same(const query *a, const query *b) {
    if (a->code != b->code) return 0;
    if (a->code != VPS_OK) return strcmp(a->err, b->err) == 0;
    vps_contact_result x = a->c, y = b->c;
    x.micros = y.micros = 0;
    return memcmp(&x, &y, sizeof x) == 0;
}

typedef struct {
    query *queries;
    size_t n;
} job;

static void *worker(void *arg) {
    job *j = arg;
    for (size_t i = 0; i < j->n; i++) run(&j->queries[i]);
    return NULL;
}

static void usage(void) {
    fprintf(stderr, "usage: contact [-t THREADS] [-b BUDGET_US] [-l | -s] VXM VPS STIFFNESS [POSES]\n");
    exit(2);
}

int main(int argc, char **argv) {
    int threads = 1, a = 1;
    for (; a < argc && argv[a][0] == '-' && argv[a][1]; a++) {
        if (!strcmp(argv[a], "-t") && a + 1 < argc) {
            threads = atoi(argv[++a]);
        } else if (!strcmp(argv[a], "-b") && a + 1 < argc) {
            budget_us = strtod(argv[++a], NULL);
        } else if (!strcmp(argv[a], "-l")) {
            penetration = VPS_PENETRATION_LAYERS;
        } else if (!strcmp(argv[a], "-s")) {
            penetration = VPS_PENETRATION_SHARP;
        } else {
            usage();
        }
    }
    if (argc - a < 3 || argc - a > 4 || threads < 1) usage();
    vxm_path = argv[a];
    vps_path = argv[a + 1];
    char *end;
    stiffness = strtod(argv[a + 2], &end);
    if (end == argv[a + 2] || *end) usage();
    FILE *in = stdin;
    if (argc - a == 4 && strcmp(argv[a + 3], "-")) {
        in = fopen(argv[a + 3], "r");
        if (!in) {
            fprintf(stderr, "contact: cannot open %s: %s\n", argv[a + 3], strerror(errno));
            return 2;
        }
    }
    open_files();

    int failed = 0;
    size_t n = 0, cap = 0;
    query *all = NULL;
    char line[4096];
    while (fgets(line, sizeof line, in)) {
        const char *p = line;
        while (*p == ' ' || *p == '\t') p++;
        if (!*p || *p == '\n' || *p == '\r' || *p == '#') continue;
        if (!strncmp(p, "reopen", 6)) {
            close_files();
            open_files();
            printf("reopened\n");
            fflush(stdout);
            continue;
        }
        query q;
        memset(&q, 0, sizeof q);
        int found = parse_pose(p, q.pose);
        if (found != 7) {
            fprintf(stderr, "contact: a pose is 7 numbers \"tx ty tz qw qx qy qz\": %s", line);
            close_files();
            return 2;
        }
        if (threads == 1) {
            run(&q);
            failed |= print(&q);
            continue;
        }
        if (n == cap) {
            cap = cap ? 2 * cap : 64;
            all = realloc(all, cap * sizeof *all);
            if (!all) {
                fprintf(stderr, "contact: out of memory\n");
                return 2;
            }
        }
        all[n++] = q;
    }

    if (threads > 1) {
        /* Each thread gets its own copy of the poses; all use the same two handles. */
        pthread_t *tid = calloc((size_t)threads, sizeof *tid);
        job *jobs = calloc((size_t)threads, sizeof *jobs);
        for (int t = 0; t < threads; t++) {
            jobs[t].n = n;
            jobs[t].queries = malloc((n ? n : 1) * sizeof(query));
            if (n) memcpy(jobs[t].queries, all, n * sizeof(query));
            if (pthread_create(&tid[t], NULL, worker, &jobs[t])) {
                fprintf(stderr, "contact: cannot start a thread\n");
                return 2;
            }
        }
        for (int t = 0; t < threads; t++) pthread_join(tid[t], NULL);
        for (int t = 1; t < threads; t++)
            for (size_t i = 0; i < n; i++)
                if (!same(&jobs[0].queries[i], &jobs[t].queries[i])) {
                    fprintf(stderr, "contact: thread %d disagrees with thread 0 on pose %zu\n", t, i);
                    failed = 1;
                }
        for (size_t i = 0; i < n; i++) failed |= print(&jobs[0].queries[i]);
        for (int t = 0; t < threads; t++) free(jobs[t].queries);
        free(jobs);
        free(tid);
    }
    free(all);
    close_files();
    if (in != stdin) fclose(in);
    return failed;
}
