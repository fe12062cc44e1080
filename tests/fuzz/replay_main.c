/* replay_main.c - the replay driver of every fuzz target (fuzz.h): `fuzz_replay_TARGET
 * FILE|DIR...` runs each file, and every regular file in each directory (sorted; README.md
 * and dot files skipped), through the target once, with every invariant checked. */
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz.h"

static int run_file(const char *path)
{
    FILE *fp = fopen(path, "rb");
    if (!fp) {
        perror(path);
        return 1;
    }
    static uint8_t buf[1u << 20];
    size_t n = fread(buf, 1, sizeof buf, fp);
    fclose(fp);
    LLVMFuzzerTestOneInput(buf, n);
    return 0;
}

static int cmp(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

int main(int argc, char **argv)
{
    unsigned files = 0;
    int rc = 0;
    for (int a = 1; a < argc; a++) {
        DIR *d = opendir(argv[a]);
        if (!d) {
            rc |= run_file(argv[a]);
            files++;
            continue;
        }
        size_t cap = 256, n = 0;
        char **names = malloc(cap * sizeof *names);
        for (struct dirent *e; names && (e = readdir(d)) != NULL;) {
            if (e->d_name[0] == '.' || strcmp(e->d_name, "README.md") == 0)
                continue;
            if (n == cap) {
                char **more = realloc(names, 2u * cap * sizeof *names);
                if (!more)
                    break;
                names = more;
                cap *= 2u;
            }
            size_t len = strlen(argv[a]) + strlen(e->d_name) + 2u;
            names[n] = malloc(len);
            if (!names[n])
                break;
            snprintf(names[n], len, "%s/%s", argv[a], e->d_name);
            n++;
        }
        closedir(d);
        if (!names) {
            perror("malloc");
            return 1;
        }
        qsort(names, n, sizeof names[0], cmp);
        for (size_t i = 0; i < n; i++) {
            rc |= run_file(names[i]);
            free(names[i]);
            files++;
        }
        free(names);
    }
    printf("%s: %u inputs replayed, every invariant held\n", fuzz_target_name, files);
    return rc;
}
