/* The paced fake servo of bench_client.py, in C so that it is never the floor.
 *
 *     paced_servo REQUEST_HEX REPLY_HEX DELAY_NS
 *
 * Opens a pseudo-terminal, prints the name of its terminal side, and then answers every
 * REQUEST heard on it with REPLY, DELAY_NS after the read that completed the request
 * returned (0: at once). It polls the pty in a tight loop and spins until the release
 * instant rather than sleeping, so no wake-up latency is added: it needs a core of its
 * own. It exits when its parent goes away. Host-side benchmark code, never firmware. */
#define _XOPEN_SOURCE 600
#define _DEFAULT_SOURCE

#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#define MAX_PACKET 256

static int64_t now_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

static size_t unhex(const char *text, uint8_t *out, size_t cap) {
    size_t n = 0;
    while (text[0] && text[1] && n < cap) {
        unsigned value;
        if (sscanf(text, "%2x", &value) != 1) {
            break;
        }
        out[n++] = (uint8_t)value;
        text += 2;
    }
    return n;
}

int main(int argc, char **argv) {
    if (argc != 4) {
        fprintf(stderr, "usage: %s REQUEST_HEX REPLY_HEX DELAY_NS\n", argv[0]);
        return 2;
    }
    uint8_t request[MAX_PACKET], reply[MAX_PACKET];
    size_t request_len = unhex(argv[1], request, sizeof request);
    size_t reply_len = unhex(argv[2], reply, sizeof reply);
    int64_t delay_ns = strtoll(argv[3], NULL, 10);
    if (request_len == 0 || reply_len == 0 || delay_ns < 0) {
        fprintf(stderr, "error: bad request, reply or delay\n");
        return 2;
    }
    int master = posix_openpt(O_RDWR | O_NOCTTY);
    if (master < 0 || grantpt(master) != 0 || unlockpt(master) != 0) {
        perror("posix_openpt");
        return 1;
    }
    const char *name = ptsname(master);
    /* held open, so the master side never reads EIO between the benchmark's opens */
    int slave = name ? open(name, O_RDWR | O_NOCTTY) : -1;
    struct termios raw;
    if (slave < 0 || tcgetattr(slave, &raw) != 0) {
        perror("pty");
        return 1;
    }
    cfmakeraw(&raw);
    tcsetattr(slave, TCSANOW, &raw);
    fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK);
    printf("%s\n", name);
    fflush(stdout);

    pid_t parent = getppid();
    uint8_t pending[2 * MAX_PACKET];
    size_t have = 0;
    unsigned long polls = 0;
    for (;;) {
        ssize_t got = read(master, pending + have, sizeof pending - have);
        if (got <= 0) {
            if (got < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
                return 0;
            }
            if ((++polls & 0xFFFFF) == 0 && getppid() != parent) {
                return 0; /* the benchmark has gone */
            }
            continue;
        }
        int64_t heard = now_ns(); /* the request's last byte is in (if it is complete) */
        have += (size_t)got;
        size_t start = 0;
        for (;;) { /* every request heard, in order */
            uint8_t *at = NULL;
            for (size_t i = start; i + request_len <= have; i++) {
                if (memcmp(pending + i, request, request_len) == 0) {
                    at = pending + i;
                    break;
                }
            }
            if (at == NULL) {
                break;
            }
            start = (size_t)(at - pending) + request_len;
            int64_t release = heard + delay_ns;
            while (now_ns() < release) {
            }
            if (write(master, reply, reply_len) != (ssize_t)reply_len) {
                return 0;
            }
            heard = release; /* a second request in the same read waits its own turn */
        }
        /* keep what may begin the next request */
        size_t keep = have - start < request_len - 1 ? have - start : request_len - 1;
        memmove(pending, pending + have - keep, keep);
        have = keep;
    }
}
