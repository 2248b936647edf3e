/* Generated from src/rovlink/protocol/commands.py by
 *     python -m rovlink.protocol.c_table firmware/c
 * Do not edit: change the command table and regenerate. */

#ifndef ROVLINK_COMMANDS_H
#define ROVLINK_COMMANDS_H

#include <stdint.h>

/* The longest whole frame, start and end characters included (P1). */
#define RL_MAX_FRAME_BYTES 64
#define RL_MAX_ARGUMENTS 2
#define RL_MAX_REPLIES 6
#define RL_NAME_BYTES 9
#define RL_SPELLING_COUNT 27

/* Flags of a command (P3, P7, P9). */
#define RL_EXACT_MATCH 0x01u   /* taken by exact match, never with a checksum */
#define RL_HONOURED_BARE 0x02u /* taken without a checksum even in checksum mode */
#define RL_MOTION 0x04u        /* dropped while the motors are locked */
#define RL_NEEDS_DIRECT 0x08u  /* dropped unless in direct mode */
#define RL_NEEDS_DEPTH 0x10u   /* dropped unless in depth mode */

typedef enum {
    RL_CMD_CRCON,
    RL_CMD_CRCOFF,
    RL_CMD_STOP,
    RL_CMD_START,
    RL_CMD_DEBUG1,
    RL_CMD_DEBUG0,
    RL_CMD_MGMP,
    RL_CMD_MVPDP,
    RL_CMD_MVPDI,
    RL_CMD_MVPIDD,
    RL_CMD_MVDIRECT,
    RL_CMD_MVS,
    RL_CMD_MVD,
    RL_CMD_TH,
    RL_CMD_QD,
    RL_CMD_QR,
    RL_CMD_SDZ,
    RL_CMD_SDK,
    RL_CMD_Q_L,
    RL_CMD_SLRESET,
    RL_CMD_QRO,
    RL_CMD_QPI,
    RL_CMD_QHE,
    RL_CMD_QSA,
    RL_CMD_H_OPEN,
    RL_CMD_H_CLOSE,
    RL_CMD_COUNT
} rl_command_id;

typedef enum {
    RL_REPLY_QD,
    RL_REPLY_QR,
    RL_REPLY_Q_L,
    RL_REPLY_QRO,
    RL_REPLY_QPI,
    RL_REPLY_QHE,
    RL_REPLY_COUNT
} rl_reply_id;

typedef struct {
    int16_t minimum;
    int16_t maximum;
    uint8_t is_signed;
} rl_argument;

/* The on/off state a command switches, and to what (P3, P5, P7, P9, P16). */
typedef enum {
    RL_SETTING_NONE,
    RL_SETTING_CHECKSUM,
    RL_SETTING_DEBUG,
    RL_SETTING_LOCKED,
    RL_SETTING_DIRECT_MODE,
    RL_SETTING_CLAW_OPEN
} rl_setting;
#define RL_FROM_ARGUMENT 2u /* the setting takes the command's 0/1 argument */

typedef struct {
    uint8_t flags;
    uint8_t setting;
    uint8_t setting_value;
    uint8_t argument_count;
    rl_argument arguments[RL_MAX_ARGUMENTS];
    uint8_t reply_count;
    uint8_t replies[RL_MAX_REPLIES];
} rl_command_spec;

typedef struct {
    char name[RL_NAME_BYTES];
    uint8_t command;
} rl_spelling;

typedef struct {
    char name[RL_NAME_BYTES];
    rl_argument argument;
} rl_reply_spec;

/* On AVR the tables live in flash (PROGMEM): read them with memcpy_P, as rovlink_proto.c does. */
#if defined(__AVR__)
#include <avr/pgmspace.h>
#define RL_ROM PROGMEM
#else
#define RL_ROM
#endif

extern const rl_command_spec rl_command_specs[RL_CMD_COUNT] RL_ROM;
extern const rl_spelling rl_spellings[RL_SPELLING_COUNT] RL_ROM;
extern const rl_reply_spec rl_reply_specs[RL_REPLY_COUNT] RL_ROM;

#endif /* ROVLINK_COMMANDS_H */
