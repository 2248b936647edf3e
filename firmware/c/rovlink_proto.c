/* rovlink C99 reference: the controller's protocol layer. See rovlink_proto.h. */
#include "rovlink_proto.h"

#include <string.h>

#define RL_BODY_BYTES (RL_MAX_FRAME_BYTES - 2)
#define RL_DEBUG_BYTES 96
/* A debug line's text: the line less its CR LF. */
#define RL_DEBUG_TEXT_BYTES (RL_DEBUG_BYTES - 2)
/* The longest number format_number writes: "-2147483648". */
#define RL_NUMBER_BYTES 11

/* Copy a table entry out of flash (AVR) or plain memory. */
static void rom_copy(void *out, const void *rom, size_t size) {
#if defined(__AVR__)
    memcpy_P(out, rom, size);
#else
    memcpy(out, rom, size);
#endif
}

/* One character of a text in flash (RL_TEXT) or, if in_flash is 0, in RAM: on AVR the two are
 * different address spaces. */
static char text_char(const char *text, size_t index, int in_flash) {
#if defined(__AVR__)
    if (in_flash) return (char)pgm_read_byte(text + index);
#else
    (void)in_flash;
#endif
    return text[index];
}

static char hex_digit(unsigned value) {
    return (char)(value < 10u ? '0' + value : 'A' + (value - 10u));
}

uint8_t rl_checksum(rl_algorithm algorithm, const char *body, size_t length) {
    uint8_t value = 0;
    size_t i;
    for (i = 0; i < length; i++) {
        uint8_t byte = (uint8_t)body[i];
        if (algorithm == RL_XOR) {
            value ^= byte;
        } else if (algorithm == RL_SUM8) {
            value = (uint8_t)(value + byte);
        } else { /* CRC-8/SMBUS: poly 0x07, init 0, no reflection (P2) */
            int bit;
            value ^= byte;
            for (bit = 0; bit < 8; bit++) {
                uint8_t carry = (uint8_t)(value & 0x80u);
                value = (uint8_t)(value << 1);
                if (carry) value ^= 0x07u;
            }
        }
    }
    return value;
}

static int hex_value(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    if (c >= 'a' && c <= 'f') return c - 'a' + 10; /* receivers accept lowercase (P2) */
    return -1;
}

static void write_bytes(rl_link *link, const char *data, size_t length) {
    link->app->write(link->context, data, length);
}

/* A debug line as it is built: one buffer on the stack, whatever goes into it. */
typedef struct {
    char bytes[RL_DEBUG_BYTES];
    size_t length;
} debug_line;

/* Append a text up to a line length of limit. Nothing in a debug line may look like a frame
 * (P5): '#', '$', '!' and bytes that are not printable become '?'. */
static void line_add(debug_line *line, const char *text, int in_flash, size_t limit) {
    size_t i;
    char c;
    for (i = 0; line->length < limit && (c = text_char(text, i, in_flash)) != '\0'; i++) {
        line->bytes[line->length++] =
            (c == '#' || c == '$' || c == '!' || c < 0x20 || c > 0x7e) ? '?' : c;
    }
}

static void line_start(debug_line *line) {
    line->length = 0;
    line_add(line, RL_TEXT("debug: "), 1, RL_DEBUG_TEXT_BYTES);
}

static void line_end(rl_link *link, debug_line *line) {
    line->bytes[line->length++] = '\r';
    line->bytes[line->length++] = '\n';
    write_bytes(link, line->bytes, line->length);
}

static void debug_text(rl_link *link, const char *text, int in_flash) {
    debug_line line;
    if (!link->debug_on) return;
    line_start(&line);
    line_add(&line, text, in_flash, RL_DEBUG_TEXT_BYTES);
    line_end(link, &line);
}

void rl_debug(rl_link *link, const char *text) { debug_text(link, text, 0); }

void rl_debug_flash(rl_link *link, const char *text) { debug_text(link, text, 1); }

/* "dropped <body>: why" as a debug line; why is in flash (RL_TEXT). */
static void drop(rl_link *link, const char *why) {
    debug_line line;
    size_t body, i;
    if (!link->debug_on) return;
    line_start(&line);
    line_add(&line, RL_TEXT("dropped <"), 1, RL_DEBUG_TEXT_BYTES);
    body = link->length < 24 ? link->length : 24;
    for (i = 0; i < body; i++) line.bytes[line.length++] = link->buffer[i]; /* 0x21-0x7E */
    if (body < link->length) line_add(&line, RL_TEXT("..."), 1, RL_DEBUG_TEXT_BYTES);
    line_add(&line, RL_TEXT(">: "), 1, RL_DEBUG_TEXT_BYTES);
    line_add(&line, why, 1, RL_DEBUG_TEXT_BYTES);
    line_end(link, &line);
}

void rl_init(rl_link *link, const rl_app *app, void *context, rl_algorithm algorithm) {
    memset(link, 0, sizeof *link);
    link->app = app;
    link->context = context;
    link->algorithm = (uint8_t)algorithm;
    link->locked = 1;
}

void rl_rx_lost(rl_link *link) {
    if (link->in_frame && !link->too_long) {
        drop(link, RL_TEXT("bytes lost in it (receive overrun)"));
    }
    link->in_frame = 0;
}

void rl_lock(rl_link *link, const char *why) {
    link->locked = 1;
    debug_text(link, why, 0);
}

void rl_lock_flash(rl_link *link, const char *why) {
    link->locked = 1;
    debug_text(link, why, 1);
}

/* A decimal number at out (at most RL_NUMBER_BYTES): no leading zeros; with_sign: always a
 * sign, zero as +0 (P6, P15), else a '-' on negative values only. Returns its length. */
static size_t format_number(char *out, int32_t value, int with_sign) {
    char digits[10];
    int count = 0;
    size_t length = 0;
    uint32_t magnitude = value < 0 ? (uint32_t)(-(value + 1)) + 1u : (uint32_t)value;
    if (value < 0) {
        out[length++] = '-';
    } else if (with_sign) {
        out[length++] = '+';
    }
    do {
        digits[count++] = (char)('0' + magnitude % 10u);
        magnitude /= 10u;
    } while (magnitude);
    while (count) out[length++] = digits[--count];
    return length;
}

static void debug_number(rl_link *link, const char *before, int32_t value, int with_sign,
                         const char *after, int in_flash) {
    debug_line line;
    if (!link->debug_on) return;
    line_start(&line);
    line_add(&line, before, in_flash, RL_DEBUG_TEXT_BYTES - RL_NUMBER_BYTES); /* room for it */
    line.length += format_number(line.bytes + line.length, value, with_sign);
    line_add(&line, after, in_flash, RL_DEBUG_TEXT_BYTES);
    line_end(link, &line);
}

void rl_debug_number(rl_link *link, const char *before, int32_t value, int with_sign,
                     const char *after) {
    debug_number(link, before, value, with_sign, after, 0);
}

void rl_debug_number_flash(rl_link *link, const char *before, int32_t value, int with_sign,
                           const char *after) {
    debug_number(link, before, value, with_sign, after, 1);
}

size_t rl_format_reply(const rl_link *link, rl_reply_id reply, int32_t value, char *out) {
    rl_reply_spec spec;
    size_t length = 0, name_length, body_start = 1;
    rom_copy(&spec, &rl_reply_specs[reply], sizeof spec);
    /* Written as the protocol writes it, whatever the sensor gave (P13, P15): a heading 0-359
     * (360 is 0, as 359.6 rounds to it), every other value within its reply's range. */
    if (reply == RL_REPLY_QHE) {
        value %= 360;
        if (value < 0) value += 360;
    } else if (value < spec.argument.minimum) {
        value = spec.argument.minimum;
    } else if (value > spec.argument.maximum) {
        value = spec.argument.maximum;
    }
    out[length++] = '$';
    name_length = strlen(spec.name);
    memcpy(out + length, spec.name, name_length);
    length += name_length;
    out[length++] = '.';
    length += format_number(out + length, value, spec.argument.is_signed);
    if (link->checksum_on) {
        uint8_t sum = rl_checksum((rl_algorithm)link->algorithm, out + body_start,
                                  length - body_start);
        out[length++] = hex_digit(sum >> 4);
        out[length++] = hex_digit(sum & 0x0fu);
    }
    out[length++] = '!';
    return length;
}

/* The spelling the body (or its part before a '.') names: the longest match first (q.l). */
static int find_command(const char *body, size_t length, size_t *name_length) {
    size_t cut = length;
    for (;;) {
        size_t i;
        for (i = 0; i < RL_SPELLING_COUNT; i++) {
            rl_spelling spelling;
            rom_copy(&spelling, &rl_spellings[i], sizeof spelling);
            if (strlen(spelling.name) == cut && memcmp(spelling.name, body, cut) == 0) {
                *name_length = cut;
                return spelling.command;
            }
        }
        while (cut > 0 && body[--cut] != '.') {
        }
        if (cut == 0) return -1;
    }
}

/* A decimal integer (P6): leading zeros accepted, a sign only where signed. */
static int parse_number(const char *text, size_t length, int is_signed, int32_t *value) {
    size_t i = 0;
    int negative = 0;
    int32_t result = 0;
    if (is_signed && length && (text[0] == '+' || text[0] == '-')) {
        negative = text[0] == '-';
        i = 1;
    }
    if (i == length) return 0;
    for (; i < length; i++) {
        if (text[i] < '0' || text[i] > '9') return 0;
        if (result < 100000) result = result * 10 + (text[i] - '0'); /* beyond every range */
    }
    *value = negative ? -result : result;
    return 1;
}

static void reply(rl_link *link, const rl_command_spec *spec) {
    uint8_t i;
    for (i = 0; i < spec->reply_count; i++) {
        char out[RL_REPLY_BYTES];
        rl_reply_id id = (rl_reply_id)spec->replies[i];
        size_t length = rl_format_reply(link, id, link->app->reply_value(link->context, id), out);
        write_bytes(link, out, length);
    }
}

/* (A function, not a table of pointers: on AVR the texts stay in flash.) */
static const char *checksum_on_line(uint8_t algorithm) {
    switch (algorithm) {
    case RL_XOR: return RL_TEXT("checksum mode on (xor)");
    case RL_SUM8: return RL_TEXT("checksum mode on (sum8)");
    default: return RL_TEXT("checksum mode on (crc8)");
    }
}

/* Switch the layer's own state for a setting and write its debug line (P5); 0 if the command
 * goes no further: a mode frame, or a start or mvdirect that changes nothing (the app is told
 * only of changes, so that a repeated #start! keeps the set-points, P11), or a stop, which the
 * app is told of here, before its line is written: on a slow line the write may wait, and the
 * outputs go to neutral first. */
static int apply_setting(rl_link *link, const rl_command_spec *spec, rl_command_id command,
                         const int32_t *values) {
    uint8_t on = spec->setting_value == RL_FROM_ARGUMENT ? (uint8_t)(values[0] != 0)
                                                         : spec->setting_value;
    switch (spec->setting) {
    case RL_SETTING_CHECKSUM:
        link->checksum_on = on; /* from the next frame on, both directions (P3) */
        rl_debug_flash(link, on ? checksum_on_line(link->algorithm) : RL_TEXT("checksum mode off"));
        return 0;
    case RL_SETTING_DEBUG:
        if (on == link->debug_on) return 0;
        if (!on) rl_debug_flash(link, RL_TEXT("debug output off"));
        link->debug_on = on;
        if (on) rl_debug_flash(link, RL_TEXT("debug output on"));
        return 0;
    case RL_SETTING_LOCKED:
        if (on) {
            link->locked = 1;
            link->app->command(link->context, command, values);
            rl_debug_flash(link, RL_TEXT("stop command: motors stopped and locked"));
            return 0;
        }
        if (!link->locked) {
            rl_debug_flash(link, RL_TEXT("start: motors already unlocked, nothing changed"));
            return 0;
        }
        link->locked = 0;
        rl_debug_flash(link, RL_TEXT("motors unlocked"));
        return 1;
    case RL_SETTING_DIRECT_MODE:
        if (on == link->direct_mode) {
            rl_debug_flash(link, on ? RL_TEXT("vertical mode already direct, nothing changed")
                                    : RL_TEXT("vertical mode already depth, nothing changed"));
            return 0;
        }
        link->direct_mode = on;
        if (!on && !link->locked) { /* the app holds the current depth (P9) */
            rl_debug_number_flash(link, RL_TEXT("vertical mode depth, holding "),
                                  link->app->reply_value(link->context, RL_REPLY_QD), 0,
                                  RL_TEXT(" cm"));
        } else {
            rl_debug_flash(link, on ? RL_TEXT("vertical mode direct, vertical thrust 0")
                                    : RL_TEXT("vertical mode depth, vertical thrust 0"));
        }
        return 1;
    default:
        return 1;
    }
}

static int parse_arguments(const char *text, size_t length, const rl_command_spec *spec,
                           int32_t *values, const char **why) {
    size_t start = 0, i;
    uint8_t count = 0;
    for (i = 0; i <= length; i++) {
        if (i < length && text[i] != '.') continue;
        if (count == spec->argument_count) {
            *why = RL_TEXT("too many arguments");
            return 0;
        }
        if (!parse_number(text + start, i - start, spec->arguments[count].is_signed,
                          &values[count])) {
            *why = RL_TEXT("not a number");
            return 0;
        }
        if (values[count] < spec->arguments[count].minimum ||
            values[count] > spec->arguments[count].maximum) {
            *why = RL_TEXT("out of range"); /* dropped, never clamped (P6) */
            return 0;
        }
        count++;
        start = i + 1;
    }
    if (count != spec->argument_count) {
        *why = RL_TEXT("too few arguments");
        return 0;
    }
    return 1;
}

static void handle_frame(rl_link *link) {
    const char *body = link->buffer;
    size_t length = link->length;
    size_t name_length = 0;
    int found;
    rl_command_spec spec;
    int32_t values[RL_MAX_ARGUMENTS] = {0};
    const char *why = RL_TEXT("");

    if (link->start != '#') {
        drop(link, RL_TEXT("a reply, not a command"));
        return;
    }
    found = find_command(body, length, &name_length);
    if (found >= 0) rom_copy(&spec, &rl_command_specs[found], sizeof spec);
    /* Mode frames by exact match, in either mode, before any checksum is stripped (P3). */
    if (found >= 0 && name_length == length && (spec.flags & RL_EXACT_MATCH)) {
        link->valid_frames++;
        apply_setting(link, &spec, (rl_command_id)found, values);
        return;
    }
    if (link->checksum_on && !(found >= 0 && name_length == length &&
                               (spec.flags & RL_HONOURED_BARE))) {
        int high, low;
        if (length < 3) {
            drop(link, RL_TEXT("missing or wrong checksum"));
            return;
        }
        high = hex_value(body[length - 2]);
        low = hex_value(body[length - 1]);
        if (high < 0 || low < 0 ||
            rl_checksum((rl_algorithm)link->algorithm, body, length - 2) !=
                (uint8_t)(high * 16 + low)) {
            drop(link, RL_TEXT("missing or wrong checksum"));
            return;
        }
        length -= 2;
        found = find_command(body, length, &name_length);
        if (found >= 0) rom_copy(&spec, &rl_command_specs[found], sizeof spec);
    }
    if (found < 0) {
        drop(link, RL_TEXT("unknown command"));
        return;
    }
    if (spec.flags & RL_EXACT_MATCH) {
        drop(link, RL_TEXT("crcon and crcoff never carry a checksum"));
        return;
    }
    if (spec.argument_count == 0 && name_length != length) {
        drop(link, RL_TEXT("takes no argument"));
        return;
    }
    if (spec.argument_count > 0) {
        if (name_length == length || body[name_length] != '.') {
            drop(link, RL_TEXT("needs arguments"));
            return;
        }
        if (!parse_arguments(body + name_length + 1, length - name_length - 1, &spec, values,
                             &why)) {
            drop(link, why);
            return;
        }
    }
    link->valid_frames++; /* any valid command keeps the link alive (P17), even one dropped */
    if ((spec.flags & RL_MOTION) && link->locked) {
        drop(link, RL_TEXT("motors are locked; send start first"));
        return;
    }
    if (((spec.flags & RL_NEEDS_DIRECT) && !link->direct_mode) ||
        ((spec.flags & RL_NEEDS_DEPTH) && link->direct_mode)) {
        drop(link, RL_TEXT("not in this vertical mode"));
        return;
    }
    if (spec.reply_count) {
        reply(link, &spec);
        return;
    }
    if (apply_setting(link, &spec, (rl_command_id)found, values)) {
        link->app->command(link->context, (rl_command_id)found, values);
    }
}

void rl_feed(rl_link *link, const uint8_t *data, size_t length) {
    size_t i;
    for (i = 0; i < length; i++) {
        uint8_t byte = data[i];
        if (byte == '#' || byte == '$') {
            if (link->in_frame && !link->too_long) {
                drop(link, RL_TEXT("a new frame started before its end"));
            }
            link->in_frame = 1;
            link->too_long = 0;
            link->length = 0;
            link->start = byte;
        } else if (!link->in_frame) {
            /* between frames: line breaks, spaces, noise (P1) */
        } else if (byte == '!') {
            link->in_frame = 0;
            if (!link->too_long) handle_frame(link);
        } else if (byte < 0x21 || byte > 0x7e) {
            link->in_frame = 0;
            if (!link->too_long) drop(link, RL_TEXT("a byte outside 0x21-0x7E"));
        } else if (link->too_long) {
            /* the rest of a frame dropped already: skipped up to its end */
        } else if (link->length < RL_BODY_BYTES) {
            link->buffer[link->length++] = (char)byte;
        } else { /* dropped as soon as it is too long, whether or not it ever ends */
            link->too_long = 1;
            drop(link, RL_TEXT("longer than 64 bytes"));
        }
    }
}
