/* qemu-insnmark: a QEMU TCG plugin (plugin API v1, as in Debian bookworm's
 * qemu-system-arm 7.2, which ships no plugin binaries and no plugin header)
 * that counts the guest instructions executed between two marker addresses.
 *
 * Adapted from an earlier version kept with the rollcal project notes
 * (outside this repository; this file is the maintained one).
 * Build:  gcc -shared -fPIC -O2 -o libinsnmark.so insnmark.c
 * Use:    qemu-system-arm ... -plugin ./libinsnmark.so,start=0xADDR,end=0xADDR[,first=N][,syms=N][,out=FILE] -d plugin
 *
 * Every executed guest instruction adds one to a counter (inline add). When
 * the instruction at `start` executes, the count is noted; when the one at
 * `end` executes, the difference (the instructions from the first instruction
 * of the start marker up to, excluding, the first instruction of the end
 * marker) is one "region". At exit it prints:
 *   insnmark: regions=K mean=M min=A max=B
 *   insnmark: first N: d1 d2 ...            (first=N, default 5)
 *   insnmark: after first N: mean=.. min=.. max=..
 *   insnmark: total insns=T
 * and, with syms=N, the N functions (ELF symbols) with the most instructions
 * executed inside regions (per translation block, so a block left early by
 * an exception counts whole; negligible here). out=FILE writes one delta per
 * line. With memcallers=N it also prints the N call sites (the last
 * block executed outside a mem* function before it, with its symbol) whose
 * calls into memcpy/memset/memclr/memmove cost the most instructions inside
 * regions (softfloat=1: calls into the f64 soft-float routines too, the
 * M4F's emulated double precision; callee=NAME: only calls into the
 * routines whose symbol contains NAME, e.g. callee=__aeabi_d2f). With blocks=N it prints the N
 * translation blocks (address, length, runs) with the most instructions
 * inside regions: the hot loops of a function. Counts are exact and repeat run to run (no timing model involved).
 */
#include <inttypes.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef uint64_t qemu_plugin_id_t;
typedef struct qemu_info_t qemu_info_t;
struct qemu_plugin_tb;
struct qemu_plugin_insn;
enum qemu_plugin_cb_flags { QEMU_PLUGIN_CB_NO_REGS, QEMU_PLUGIN_CB_R_REGS, QEMU_PLUGIN_CB_RW_REGS };
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 };
typedef void (*qemu_plugin_udata_cb_t)(qemu_plugin_id_t, void *);
typedef void (*qemu_plugin_vcpu_udata_cb_t)(unsigned int, void *);
typedef void (*qemu_plugin_vcpu_tb_trans_cb_t)(qemu_plugin_id_t, struct qemu_plugin_tb *);
void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t, qemu_plugin_vcpu_tb_trans_cb_t);
void qemu_plugin_register_vcpu_tb_exec_cb(struct qemu_plugin_tb *, qemu_plugin_vcpu_udata_cb_t, enum qemu_plugin_cb_flags, void *);
size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *);
struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *, size_t);
uint64_t qemu_plugin_insn_vaddr(const struct qemu_plugin_insn *);
const char *qemu_plugin_insn_symbol(const struct qemu_plugin_insn *);
void qemu_plugin_register_vcpu_insn_exec_inline(struct qemu_plugin_insn *, enum qemu_plugin_op, void *, uint64_t);
void qemu_plugin_register_vcpu_insn_exec_cb(struct qemu_plugin_insn *, qemu_plugin_vcpu_udata_cb_t, enum qemu_plugin_cb_flags, void *);
void qemu_plugin_register_atexit_cb(qemu_plugin_id_t, qemu_plugin_udata_cb_t, void *);
void qemu_plugin_outs(const char *);

__attribute__((visibility("default"))) int qemu_plugin_version = 1;

static uint64_t count, start_addr = ~0ull, end_addr = ~0ull, last_start;
static int active;
static uint64_t *deltas;
static size_t n_deltas, cap_deltas;
static unsigned first_n = 5, syms_n;
static char out_path[512];

/* Per-symbol instruction counts inside regions. */
struct sym { const char *name; uint64_t insns; };
static struct sym *syms;
static size_t n_syms, cap_syms;
struct tbinfo { size_t sym; uint64_t n; uint64_t va; int mem; uint64_t runs; };
/* blocks=N: the N translation blocks with the most instructions inside
 * regions (a block retranslated keeps one entry per translation). */
static struct tbinfo **tbs;
static size_t n_tbs, cap_tbs;
static unsigned blocks_n;
/* memcallers=N: instructions spent in mem* functions per calling block. */
struct site { uint64_t va; size_t sym; uint64_t insns; };
static struct site *sites;
static size_t n_sites, cap_sites;
static unsigned memcallers_n;
static int softfloat_too; /* softfloat=1: soft-float routines count as mem* */
static char callee[128];  /* callee=NAME: only routines whose symbol contains NAME count as mem* */
static const struct tbinfo *last_caller;

static void outf(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
#include <stdarg.h>
static void outf(const char *fmt, ...) {
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    qemu_plugin_outs(buf);
}

static void on_mark(unsigned int vcpu, void *ud) {
    (void)vcpu;
    /* The marker callback is registered before the inline add, so `count`
     * excludes the marker instruction itself at both ends. */
    if ((uintptr_t)ud == 1) {
        last_start = count;
        active = 1;
        return;
    }
    if (!active) return;
    active = 0;
    if (n_deltas == cap_deltas) {
        cap_deltas = cap_deltas ? 2 * cap_deltas : 4096;
        deltas = realloc(deltas, cap_deltas * sizeof *deltas);
        if (!deltas) abort();
    }
    deltas[n_deltas++] = count - last_start;
}

static void on_tb(unsigned int vcpu, void *ud) {
    (void)vcpu;
    struct tbinfo *t = ud;
    if (!active) return;
    syms[t->sym].insns += t->n;
    t->runs++;
    if (!memcallers_n) return;
    if (!t->mem) { last_caller = t; return; }
    if (!last_caller) return;
    size_t i;
    for (i = 0; i < n_sites; i++)
        if (sites[i].va == last_caller->va) break;
    if (i == n_sites) {
        if (n_sites == cap_sites) {
            cap_sites = cap_sites ? 2 * cap_sites : 256;
            sites = realloc(sites, cap_sites * sizeof *sites);
            if (!sites) abort();
        }
        sites[n_sites].va = last_caller->va;
        sites[n_sites].sym = last_caller->sym;
        sites[n_sites].insns = 0;
        n_sites++;
    }
    sites[i].insns += t->n;
}

/* A memory-copy/fill routine of the runtime (compiler_builtins, __aeabi_*). */
static int is_mem(const char *name) {
    if (!name) return 0;
    if (callee[0]) return strstr(name, callee) != NULL;
    if (softfloat_too && (strstr(name, "__aeabi_d") || strstr(name, "__aeabi_f2d") || strstr(name, "::float::") ||
                          strstr(name, "df3")))
        return 1;
    return strstr(name, "__aeabi_mem") || strstr(name, "mem6memcpy") || strstr(name, "mem6memset") ||
           strstr(name, "mem7memmove") || !strcmp(name, "memcpy") || !strcmp(name, "memset") ||
           !strcmp(name, "memmove") || strstr(name, "::mem::memcpy") || strstr(name, "::mem::memset") ||
           strstr(name, "::mem::memmove");
}

static int by_site(const void *a, const void *b) {
    const struct site *x = a, *y = b;
    return x->insns < y->insns ? 1 : x->insns > y->insns ? -1 : 0;
}

static size_t sym_index(const char *name) {
    if (!name) name = "?";
    for (size_t i = 0; i < n_syms; i++)
        if (syms[i].name == name || !strcmp(syms[i].name, name)) return i;
    if (n_syms == cap_syms) {
        cap_syms = cap_syms ? 2 * cap_syms : 256;
        syms = realloc(syms, cap_syms * sizeof *syms);
        if (!syms) abort();
    }
    syms[n_syms].name = strdup(name);
    syms[n_syms].insns = 0;
    return n_syms++;
}

static void tb_trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb) {
    (void)id;
    size_t n = qemu_plugin_tb_n_insns(tb);
    if ((syms_n || memcallers_n || blocks_n) && n) {
        struct tbinfo *t = malloc(sizeof *t); /* lives as long as the TB may */
        if (!t) abort();
        t->runs = 0;
        if (blocks_n) {
            if (n_tbs == cap_tbs) {
                cap_tbs = cap_tbs ? 2 * cap_tbs : 1024;
                tbs = realloc(tbs, cap_tbs * sizeof *tbs);
                if (!tbs) abort();
            }
            tbs[n_tbs++] = t;
        }
        const char *name = qemu_plugin_insn_symbol(qemu_plugin_tb_get_insn(tb, 0));
        t->sym = sym_index(name);
        t->n = n;
        t->va = qemu_plugin_insn_vaddr(qemu_plugin_tb_get_insn(tb, 0));
        t->mem = is_mem(name);
        qemu_plugin_register_vcpu_tb_exec_cb(tb, on_tb, QEMU_PLUGIN_CB_NO_REGS, t);
    }
    for (size_t i = 0; i < n; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        uint64_t va = qemu_plugin_insn_vaddr(insn);
        if (va == start_addr) qemu_plugin_register_vcpu_insn_exec_cb(insn, on_mark, QEMU_PLUGIN_CB_NO_REGS, (void *)1);
        if (va == end_addr) qemu_plugin_register_vcpu_insn_exec_cb(insn, on_mark, QEMU_PLUGIN_CB_NO_REGS, (void *)2);
        qemu_plugin_register_vcpu_insn_exec_inline(insn, QEMU_PLUGIN_INLINE_ADD_U64, &count, 1);
    }
}

static void stats(const char *what, const uint64_t *d, size_t n) {
    if (!n) { outf("insnmark: %s: none\n", what); return; }
    uint64_t mn = d[0], mx = d[0];
    long double sum = 0;
    for (size_t i = 0; i < n; i++) {
        if (d[i] < mn) mn = d[i];
        if (d[i] > mx) mx = d[i];
        sum += d[i];
    }
    outf("insnmark: %s: regions=%zu mean=%.0Lf min=%" PRIu64 " max=%" PRIu64 "\n", what, n, sum / n, mn, mx);
}

static int by_insns(const void *a, const void *b) {
    const struct sym *x = a, *y = b;
    return x->insns < y->insns ? 1 : x->insns > y->insns ? -1 : 0;
}

static int by_block(const void *a, const void *b) {
    const struct tbinfo *x = *(struct tbinfo *const *)a, *y = *(struct tbinfo *const *)b;
    uint64_t u = x->runs * x->n, v = y->runs * y->n;
    return u < v ? 1 : u > v ? -1 : 0;
}

static void at_exit(qemu_plugin_id_t id, void *p) {
    (void)id; (void)p;
    stats("all", deltas, n_deltas);
    if (n_deltas) {
        char line[480];
        size_t k = first_n < n_deltas ? first_n : n_deltas, o = 0;
        for (size_t i = 0; i < k && o + 24 < sizeof line; i++)
            o += snprintf(line + o, sizeof line - o, " %" PRIu64, deltas[i]);
        outf("insnmark: first %zu:%s\n", k, line);
    }
    if (n_deltas > first_n) {
        char what[64];
        snprintf(what, sizeof what, "after first %u", first_n);
        stats(what, deltas + first_n, n_deltas - first_n);
    }
    if (memcallers_n && n_sites) {
        uint64_t in = 0;
        for (size_t i = 0; i < n_sites; i++) in += sites[i].insns;
        qsort(sites, n_sites, sizeof *sites, by_site);
        outf("insnmark: mem* call sites inside regions (%" PRIu64 " insns in mem* in all; block before the call):\n", in);
        for (size_t i = 0; i < n_sites && i < memcallers_n; i++)
            outf("insnmark: mem %6.2f%% %12" PRIu64 "  0x%08" PRIx64 " %s\n", 100.0 * sites[i].insns / (in ? in : 1),
                 sites[i].insns, sites[i].va, syms[sites[i].sym].name);
    }
    if (syms_n && n_syms) {
        uint64_t in = 0;
        for (size_t i = 0; i < n_syms; i++) in += syms[i].insns;
        qsort(syms, n_syms, sizeof *syms, by_insns);
        outf("insnmark: top functions inside regions (%" PRIu64 " insns in all):\n", in);
        for (size_t i = 0; i < n_syms && i < syms_n && syms[i].insns; i++)
            outf("insnmark: %6.2f%% %14" PRIu64 "  %s\n", 100.0 * syms[i].insns / (in ? in : 1), syms[i].insns, syms[i].name);
    }
    if (blocks_n && n_tbs) {
        uint64_t in = 0;
        for (size_t i = 0; i < n_tbs; i++) in += tbs[i]->runs * tbs[i]->n;
        qsort(tbs, n_tbs, sizeof *tbs, by_block);
        outf("insnmark: top blocks inside regions (%" PRIu64 " insns in all; address, instructions, runs):\n", in);
        for (size_t i = 0; i < n_tbs && i < blocks_n && tbs[i]->runs; i++)
            outf("insnmark: block %6.2f%% %12" PRIu64 "  0x%08" PRIx64 " %3" PRIu64 " x %-9" PRIu64 " %s\n",
                 100.0 * tbs[i]->runs * tbs[i]->n / (in ? in : 1), tbs[i]->runs * tbs[i]->n, tbs[i]->va, tbs[i]->n,
                 tbs[i]->runs, syms[tbs[i]->sym].name);
    }
    if (out_path[0]) {
        FILE *f = fopen(out_path, "w");
        if (f) {
            for (size_t i = 0; i < n_deltas; i++) fprintf(f, "%" PRIu64 "\n", deltas[i]);
            fclose(f);
        }
    }
    outf("insnmark: total insns=%" PRIu64 "\n", count);
}

__attribute__((visibility("default")))
int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info, int argc, char **argv) {
    (void)info;
    for (int i = 0; i < argc; i++) {
        if (!strncmp(argv[i], "start=", 6)) start_addr = strtoull(argv[i] + 6, NULL, 0) & ~1ull;
        else if (!strncmp(argv[i], "end=", 4)) end_addr = strtoull(argv[i] + 4, NULL, 0) & ~1ull;
        else if (!strncmp(argv[i], "first=", 6)) first_n = (unsigned)strtoul(argv[i] + 6, NULL, 0);
        else if (!strncmp(argv[i], "syms=", 5)) syms_n = (unsigned)strtoul(argv[i] + 5, NULL, 0);
        else if (!strncmp(argv[i], "memcallers=", 11)) memcallers_n = (unsigned)strtoul(argv[i] + 11, NULL, 0);
        else if (!strncmp(argv[i], "blocks=", 7)) blocks_n = (unsigned)strtoul(argv[i] + 7, NULL, 0);
        else if (!strncmp(argv[i], "softfloat=", 10)) softfloat_too = atoi(argv[i] + 10);
        else if (!strncmp(argv[i], "callee=", 7)) snprintf(callee, sizeof callee, "%s", argv[i] + 7);
        else if (!strncmp(argv[i], "out=", 4)) snprintf(out_path, sizeof out_path, "%s", argv[i] + 4);
        else { outf("insnmark: unknown argument %s\n", argv[i]); return -1; }
    }
    if (start_addr == ~0ull || end_addr == ~0ull) {
        outf("insnmark: start=ADDR and end=ADDR are required\n");
        return -1;
    }
    qemu_plugin_register_vcpu_tb_trans_cb(id, tb_trans);
    qemu_plugin_register_atexit_cb(id, at_exit, NULL);
    return 0;
}
