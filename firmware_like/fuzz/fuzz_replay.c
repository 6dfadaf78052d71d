/*
 * fuzz_replay.c - runs a libFuzzer harness's LLVMFuzzerTestOneInput over files, without libFuzzer: the corpora and
 * the regression inputs replay in every build (ctest fuzz_replay_*, and under ASan + UBSan in build-asan) on any
 * compiler. A harness reports a broken property with abort(); a sanitizer, where built in, reports the rest.
 *
 *   fuzz_replay_NAME PATH...     each PATH a file, or a directory whose files (not its subdirectories) are inputs
 *
 * Exit 0 when every input ran; 1 when no input was found (an empty corpus must not pass) or one could not be read.
 * C99 with POSIX directory calls; no heap: an input is read into a static buffer (inputs above 1 MiB are refused).
 */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define MAX_INPUT (1L << 20)
static uint8_t g_input[MAX_INPUT];
static char g_path[4096];
static long g_inputs, g_failed;

static void run_file(const char *path)
{
    FILE *f = fopen(path, "rb");
    size_t n;
    if (!f) {
        fprintf(stderr, "fuzz_replay: cannot open %s\n", path);
        ++g_failed;
        return;
    }
    n = fread(g_input, 1, sizeof g_input, f);
    if (ferror(f) || (n == sizeof g_input && fgetc(f) != EOF)) {
        fprintf(stderr, "fuzz_replay: %s: read error or larger than %ld bytes\n", path, MAX_INPUT);
        ++g_failed;
        fclose(f);
        return;
    }
    fclose(f);
    LLVMFuzzerTestOneInput(g_input, n);
    ++g_inputs;
}

static void run_path(const char *path)
{
    struct stat st;
    DIR *d;
    struct dirent *e;
    if (stat(path, &st) != 0) {
        fprintf(stderr, "fuzz_replay: no such file or directory: %s\n", path);
        ++g_failed;
        return;
    }
    if (!S_ISDIR(st.st_mode)) {
        run_file(path);
        return;
    }
    d = opendir(path);
    if (!d) {
        fprintf(stderr, "fuzz_replay: cannot read the directory %s\n", path);
        ++g_failed;
        return;
    }
    while ((e = readdir(d)) != 0) {
        if (e->d_name[0] == '.') {
            continue;
        }
        if ((size_t)snprintf(g_path, sizeof g_path, "%s/%s", path, e->d_name) >= sizeof g_path) {
            fprintf(stderr, "fuzz_replay: path too long in %s\n", path);
            ++g_failed;
            continue;
        }
        if (stat(g_path, &st) == 0 && S_ISREG(st.st_mode)) {
            run_file(g_path);
        }
    }
    closedir(d);
}

int main(int argc, char **argv)
{
    int i;
    for (i = 1; i < argc; ++i) {
        run_path(argv[i]);
    }
    printf("fuzz_replay: %ld inputs run, %ld unreadable\n", g_inputs, g_failed);
    if (g_inputs == 0) {
        fprintf(stderr, "fuzz_replay: no input found\n");
        return 1;
    }
    return g_failed ? 1 : 0;
}
