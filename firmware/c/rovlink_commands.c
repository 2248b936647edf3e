/* Generated from src/rovlink/protocol/commands.py by
 *     python -m rovlink.protocol.c_table firmware/c
 * Do not edit: change the command table and regenerate. */

#include "rovlink_commands.h"

const rl_command_spec rl_command_specs[RL_CMD_COUNT] RL_ROM = {
    /* crcon */ {RL_EXACT_MATCH, RL_SETTING_CHECKSUM, 1, 0, {{0, 0, 0}}, 0, {0}},
    /* crcoff */ {RL_EXACT_MATCH, RL_SETTING_CHECKSUM, 0, 0, {{0, 0, 0}}, 0, {0}},
    /* stop */ {RL_HONOURED_BARE, RL_SETTING_LOCKED, 1, 0, {{0, 0, 0}}, 0, {0}},
    /* start */ {0, RL_SETTING_LOCKED, 0, 0, {{0, 0, 0}}, 0, {0}},
    /* debug1 */ {0, RL_SETTING_DEBUG, 1, 0, {{0, 0, 0}}, 0, {0}},
    /* debug0 */ {0, RL_SETTING_DEBUG, 0, 0, {{0, 0, 0}}, 0, {0}},
    /* mgmp */ {0, RL_SETTING_NONE, 0, 1, {{0, 255, 0}}, 0, {0}},
    /* mvpdp */ {0, RL_SETTING_NONE, 0, 1, {{0, 99, 0}}, 0, {0}},
    /* mvpdi */ {0, RL_SETTING_NONE, 0, 1, {{0, 99, 0}}, 0, {0}},
    /* mvpidd */ {0, RL_SETTING_NONE, 0, 1, {{0, 99, 0}}, 0, {0}},
    /* mvdirect */ {0, RL_SETTING_DIRECT_MODE, RL_FROM_ARGUMENT, 1, {{0, 1, 0}}, 0, {0}},
    /* mvs */ {RL_MOTION | RL_NEEDS_DIRECT, RL_SETTING_NONE, 0, 1, {{-100, 100, 1}}, 0, {0}},
    /* mvd */ {RL_MOTION | RL_NEEDS_DEPTH, RL_SETTING_NONE, 0, 1, {{0, 9999, 0}}, 0, {0}},
    /* th */ {RL_MOTION, RL_SETTING_NONE, 0, 2, {{0, 360, 0}, {0, 100, 0}}, 0, {0}},
    /* qd */ {0, RL_SETTING_NONE, 0, 0, {{0, 0, 0}}, 1, {RL_REPLY_QD}},
    /* qr */ {0, RL_SETTING_NONE, 0, 0, {{0, 0, 0}}, 1, {RL_REPLY_QR}},
    /* sdz */ {0, RL_SETTING_NONE, 0, 1, {{0, 1024, 0}}, 0, {0}},
    /* sdk */ {0, RL_SETTING_NONE, 0, 1, {{0, 10000, 0}}, 0, {0}},
    /* q.l */ {0, RL_SETTING_NONE, 0, 0, {{0, 0, 0}}, 1, {RL_REPLY_Q_L}},
    /* slreset */ {0, RL_SETTING_NONE, 0, 0, {{0, 0, 0}}, 0, {0}},
    /* qro */ {0, RL_SETTING_NONE, 0, 0, {{0, 0, 0}}, 1, {RL_REPLY_QRO}},
    /* qpi */ {0, RL_SETTING_NONE, 0, 0, {{0, 0, 0}}, 1, {RL_REPLY_QPI}},
    /* qhe */ {0, RL_SETTING_NONE, 0, 0, {{0, 0, 0}}, 1, {RL_REPLY_QHE}},
    /* qsa */ {0, RL_SETTING_NONE, 0, 0, {{0, 0, 0}}, 6, {RL_REPLY_QD, RL_REPLY_QR, RL_REPLY_Q_L, RL_REPLY_QRO, RL_REPLY_QPI, RL_REPLY_QHE}},
    /* h+ */ {RL_MOTION, RL_SETTING_CLAW_OPEN, 1, 0, {{0, 0, 0}}, 0, {0}},
    /* h- */ {RL_MOTION, RL_SETTING_CLAW_OPEN, 0, 0, {{0, 0, 0}}, 0, {0}}
};

const rl_spelling rl_spellings[RL_SPELLING_COUNT] RL_ROM = {
    {"crcon", RL_CMD_CRCON},
    {"crcoff", RL_CMD_CRCOFF},
    {"stop", RL_CMD_STOP},
    {"start", RL_CMD_START},
    {"debug1", RL_CMD_DEBUG1},
    {"debug0", RL_CMD_DEBUG0},
    {"mgmp", RL_CMD_MGMP},
    {"mvpdp", RL_CMD_MVPDP},
    {"mvpdi", RL_CMD_MVPDI},
    {"mvpidd", RL_CMD_MVPIDD},
    {"mvpdd", RL_CMD_MVPIDD},
    {"mvdirect", RL_CMD_MVDIRECT},
    {"mvs", RL_CMD_MVS},
    {"mvd", RL_CMD_MVD},
    {"th", RL_CMD_TH},
    {"qd", RL_CMD_QD},
    {"qr", RL_CMD_QR},
    {"sdz", RL_CMD_SDZ},
    {"sdk", RL_CMD_SDK},
    {"q.l", RL_CMD_Q_L},
    {"slreset", RL_CMD_SLRESET},
    {"qro", RL_CMD_QRO},
    {"qpi", RL_CMD_QPI},
    {"qhe", RL_CMD_QHE},
    {"qsa", RL_CMD_QSA},
    {"h+", RL_CMD_H_OPEN},
    {"h-", RL_CMD_H_CLOSE}
};

const rl_reply_spec rl_reply_specs[RL_REPLY_COUNT] RL_ROM = {
    {"qd", {0, 9999, 0}},
    {"qr", {0, 1024, 0}},
    {"q.l", {0, 1, 0}},
    {"qro", {-90, 90, 1}},
    {"qpi", {-90, 90, 1}},
    {"qhe", {0, 360, 0}}
};
