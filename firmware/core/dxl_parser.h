/* Streaming Protocol 1.0 parser: finds packets in a byte stream and reports what it has
 * to drop. No heap, one fixed buffer, every index a wrapping uint8_t. dxl_parser_feed is
 * O(1); dxl_parser_poll does at most one checksum pass (<= DXL_MAX_PACKET bytes) per event
 * plus one step per byte it drops. Fit for an interrupt handler or for a main loop
 * draining a ring buffer:
 *
 *     dxl_parser_feed(&p, byte);
 *     while (dxl_parser_poll(&p, &ev)) { ...handle ev... }
 *
 * One byte can complete several events (a rejected candidate may hide a packet), hence
 * feed-then-poll. Resynchronisation rule (the Python parser, snakebot.formats.protocol.parser,
 * follows it packet for packet; see protocol/README.md): with B the unconsumed bytes,
 * (1) drop bytes until B starts with FF FF (a lone trailing FF is kept); (2) while
 * B[2] == FF drop one byte; (3) if LEN = B[3] < 2 or LEN + 4 > DXL_MAX_PACKET report a
 * length rejection of B[0..3] and drop one byte; (4) once LEN + 4 bytes are there, report
 * a checksum rejection of them and drop one byte if the checksum is wrong, otherwise
 * report the packet and drop it. */
#ifndef SNAKEBOT_DXL_PARSER_H
#define SNAKEBOT_DXL_PARSER_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "dxl_packet.h"

/* cffi:begin */
/* Event kinds. */
#define DXL_EVENT_PACKET 1
#define DXL_EVENT_BAD_CHECKSUM 2
#define DXL_EVENT_BAD_LENGTH 3

/* Ring slots (a power of two above DXL_MAX_PACKET, so a uint8_t index wraps by itself). */
#define DXL_PARSER_RING 256
/* Storage: each byte is stored at slot and slot + DXL_PARSER_RING, so any window of
 * buffered bytes is contiguous in memory and events can point straight into it. */
#define DXL_PARSER_STORAGE 512

typedef struct {
    uint8_t kind;           /* DXL_EVENT_* */
    uint8_t id;             /* ID byte (every kind) */
    uint8_t code;           /* instruction or error byte (packet, bad checksum), else 0 */
    uint8_t nparams;        /* parameter count (packet), else 0 */
    const uint8_t *params;  /* the parameters (packet), else NULL */
    const uint8_t *raw;     /* the packet's bytes, or the bytes rejected (from FF FF) */
    uint16_t raw_len;       /* LEN + 4 (packet, bad checksum) or 4 (bad length) */
} dxl_event;

typedef struct {
    uint8_t storage[512];   /* DXL_PARSER_STORAGE */
    uint8_t start;          /* slot of the oldest unconsumed byte */
    uint8_t waiting;        /* dxl_parser_skip_to_hidden: where the first candidate it saw
                             * still short of bytes starts (UINT8_MAX: none) */
    uint16_t count;         /* unconsumed bytes, at most DXL_MAX_PACKET */
    uint16_t hunted;        /* dxl_parser_skip_to_hidden: packets ending here were checked */
} dxl_parser;

/* Empty the parser (also the initial state; a zeroed dxl_parser is already reset). */
void dxl_parser_reset(dxl_parser *p);
/* Append one byte; false (byte not taken) only if DXL_MAX_PACKET bytes wait: poll first. */
bool dxl_parser_feed(dxl_parser *p, uint8_t byte);
/* Next event into *ev (true), or false when more bytes are needed. Pointers in *ev stay
 * valid until the next dxl_parser_feed or dxl_parser_reset. */
bool dxl_parser_poll(dxl_parser *p, dxl_event *ev);
/* Bytes held back as the possible start of a packet. */
uint16_t dxl_parser_pending(const dxl_parser *p);
/* Beyond the shared rule, for a receiver that must not wait on a false header: once
 * dxl_parser_poll has returned false (the candidate at the front is incomplete), look
 * for a whole packet with a good checksum starting at a later header among the bytes
 * held back; if there is one, drop everything before it and return true (the next poll
 * reports it). Each later candidate is checksummed once, when its last byte is there,
 * and bytes are looked at again only from the first candidate still short of bytes on,
 * so the cost per byte stays O(DXL_MAX_PACKET), and is O(1) while none is held. A good
 * packet hidden inside a longer real one is taken too: a real packet's payload with
 * FF FF, a plausible LEN and a matching checksum at the right place, which the checksum
 * makes rare. */
bool dxl_parser_skip_to_hidden(dxl_parser *p);
/* For such a receiver, polling and hunting after every byte: append the bytes from
 * bytes[0..n) that can arrive with nothing to report, so they need no poll; returns how
 * many it took (0 when the next byte may matter: feed it and poll as usual). It takes
 * bytes only right after a poll and a hunt that found nothing, in the middle of a packet
 * whose header is in front, up to the byte before its last and before any header byte;
 * the parser is then as polling after each of them would have left it. */
size_t dxl_parser_feed_quiet(dxl_parser *p, const uint8_t *bytes, size_t n);
/* cffi:end */

#endif
