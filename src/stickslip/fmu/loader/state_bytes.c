/* FMU states as bytes in the loader (state_bytes.h): a state's own fields packed and unpacked by its plan. */
#include "state_bytes.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "platform.h"

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the states' bytes are little-endian: this loader copies numbers as the machine holds them"
#endif

/* ---- CPython: the functions the plans call (stable C API) ---- */
typedef void PyObject;
static struct {
    PyObject *(*PyTuple_New)(ptrdiff_t);
    int (*PyTuple_SetItem)(PyObject *, ptrdiff_t, PyObject *);
    PyObject *(*PyTuple_GetItem)(PyObject *, ptrdiff_t);
    ptrdiff_t (*PyTuple_Size)(PyObject *);
    PyObject *(*PyFloat_FromDouble)(double);
    double (*PyFloat_AsDouble)(PyObject *);
    PyObject *(*PyLong_FromLongLong)(long long);
    long long (*PyLong_AsLongLong)(PyObject *);
    PyObject *(*PyFrozenSet_New)(PyObject *);
    int (*PySequence_Contains)(PyObject *, PyObject *);
    PyObject *(*PyObject_GetAttrString)(PyObject *, const char *);
    PyObject *(*PyObject_Vectorcall)(PyObject *, PyObject *const *, size_t, PyObject *); /* CPython 3.9+, or NULL */
    char *(*PyBytes_AsString)(PyObject *);
    ptrdiff_t (*PyBytes_Size)(PyObject *);
    const char *(*PyUnicode_AsUTF8)(PyObject *);
    PyObject *(*PyErr_Occurred)(void);
    void (*PyErr_Clear)(void);
    void (*Py_IncRef)(PyObject *);
    void (*Py_DecRef)(PyObject *);
} py;
static PyObject *none, *yes, *no; /* Py_None, Py_True, Py_False */
static int resolved;                /* every function above was found (PyObject_Vectorcall may lack: then the
                                     * slave's Python unpacks every state) */

int sbf_state_bytes_resolve(void *lib)
{
#define RESOLVE(symbol) (*(void **)&py.symbol = sbf_symbol(lib, #symbol)) != NULL
    *(void **)&py.PyObject_Vectorcall = sbf_symbol(lib, "PyObject_Vectorcall");
    return resolved = RESOLVE(PyTuple_New) && RESOLVE(PyTuple_SetItem) && RESOLVE(PyTuple_GetItem) &&
           RESOLVE(PyTuple_Size) && RESOLVE(PyFloat_FromDouble) &&
           RESOLVE(PyFloat_AsDouble) && RESOLVE(PyLong_FromLongLong) && RESOLVE(PyLong_AsLongLong) &&
           RESOLVE(PyFrozenSet_New) && RESOLVE(PySequence_Contains) && RESOLVE(PyObject_GetAttrString) &&
           RESOLVE(PyBytes_AsString) && RESOLVE(PyBytes_Size) &&
           RESOLVE(PyUnicode_AsUTF8) && RESOLVE(PyErr_Occurred) && RESOLVE(PyErr_Clear) && RESOLVE(Py_IncRef) &&
           RESOLVE(Py_DecRef) && (none = sbf_symbol(lib, "_Py_NoneStruct")) != NULL &&
           (yes = sbf_symbol(lib, "_Py_TrueStruct")) != NULL && (no = sbf_symbol(lib, "_Py_FalseStruct")) != NULL;
#undef RESOLVE
}

/* ---- the plan ---- */
#define VECTORCALL_ARGUMENTS_OFFSET ((size_t)1 << (8 * sizeof(size_t) - 1)) /* PY_VECTORCALL_ARGUMENTS_OFFSET */
enum { MAX_DEPTH = 4, MAX_ENTRIES = 96, MAX_SHAPES = 8, MAX_ITEMS = 64, MAX_NAMES = 8, MAX_ALSO = 4, MAX_SECTIONS = 8 };

typedef struct {
    char code;            /* BlockStateFormat.loader_plan's: a kind (d e q B b o s), n, m, P or [ */
    int depth;            /* of the path */
    ptrdiff_t path[MAX_DEPTH];
    long size;            /* bytes in a state's bytes (-1: a part of any size) */
    int parent;           /* the shape holding the value (-1: none, a value a section's build takes) */
    int flag, count;      /* "[": the entry of its flag, the entries inside */
    size_t flag_at;       /* "[": where its flag lies in a state's bytes (the head's sizes are fixed) */
    int also[MAX_ALSO], n_also; /* "[": the entries before it whose values its build takes after its own */
    PyObject *object;     /* "m": the name (a reference held); "[": the build, or NULL */
    int bit;              /* "m": its bit among the names */
} entry;

typedef struct { /* a part of the template, for packing (object, bytes) or unpacking (offset, size in its bytes) */
    PyObject *object; /* a reference held */
    unsigned char *bytes;
    size_t offset, size;
} part;

struct sbf_state_plan {
    unsigned char *header;
    size_t header_size;
    int n, n_shapes, names;
    int sections[MAX_SECTIONS], n_sections; /* the entries "[" */
    entry entries[MAX_ENTRIES];
    int shape_depth[MAX_SHAPES];
    ptrdiff_t shape_path[MAX_SHAPES][MAX_DEPTH], shape_length[MAX_SHAPES];
    int shape_outer[MAX_SHAPES];  /* the shape holding each (-1: none, the outermost) */
    int shape_shared[MAX_SHAPES]; /* states of a run share the tuple while its entries' bytes are the same */
    int first_name;               /* the first "m" entry (-1: none), whose place the frozenset of the names takes */
    part packed[MAX_ENTRIES];        /* for "P": the template's for packing */
    PyObject *template;              /* the state unpacked last by the slave (a reference held), or NULL */
    unsigned char *template_bytes;   /* its bytes */
    size_t template_size;
    part unpacked[MAX_ENTRIES];      /* for "P": where its bytes lie in template_bytes */
    size_t template_laid[MAX_ENTRIES]; /* where each entry lies in template_bytes (layout's offsets) */
    size_t laid[MAX_ENTRIES];        /* the layout of the bytes unpacked last (layout's offsets), if laid_size */
    size_t laid_size;                /* their size (0: none laid under this template) */
    unsigned laid_sections;          /* their sections' flags, a bit each */
    PyObject *pending[1 << MAX_NAMES]; /* the frozenset of the names of each combination of "m" flags, or NULL */
    unsigned char *out;              /* the bytes packed last */
    size_t capacity;
};

/* The indexes of the tuple `path` into path[] (at most MAX_DEPTH): their count, or -1 */
static int read_path(PyObject *tuple, ptrdiff_t *path)
{
    ptrdiff_t depth = tuple ? py.PyTuple_Size(tuple) : -1;
    if (depth < 0 || depth > MAX_DEPTH) return -1;
    for (ptrdiff_t i = 0; i < depth; ++i) {
        path[i] = (ptrdiff_t)py.PyLong_AsLongLong(py.PyTuple_GetItem(tuple, i));
        if (path[i] < 0) return -1;
    }
    return (int)depth;
}

/* The shape whose path is path[0..depth), or -1 */
static int shape_of(const sbf_state_plan *plan, const ptrdiff_t *path, int depth)
{
    for (int s = 0; s < plan->n_shapes; ++s)
        if (plan->shape_depth[s] == depth && memcmp(plan->shape_path[s], path, sizeof *path * (size_t)depth) == 0)
            return s;
    return -1;
}

static long field_size(char code)
{
    switch (code) {
    case 'd': case 'e': case 'q': return 8;
    case 'B': case 'b': case 'n': case 'm': return 1;
    case 'o': case 's': return 9;
    case '[': return 0;
    default: return -2; /* "P" has its own; anything else is no code of a plan */
    }
}

/* The section `e` (entry i)'s `also` from the Python tuple `also` of entry indexes: fields placed before it; 0 if
 * malformed */
static int read_also(const sbf_state_plan *plan, int i, entry *e, PyObject *also)
{
    ptrdiff_t n = also ? py.PyTuple_Size(also) : -1;
    if (n < 0 || n > MAX_ALSO) return 0;
    for (e->n_also = 0; e->n_also < (int)n; ++e->n_also) {
        int k = (int)py.PyLong_AsLongLong(py.PyTuple_GetItem(also, e->n_also));
        if (k < 0 || k >= i || plan->entries[k].parent < 0 || field_size(plan->entries[k].code) < 8) return 0;
        e->also[e->n_also] = k;
    }
    return 1;
}

/* Entry `i` of the plan from the Python tuple (code, path, argument); 0 if malformed */
static int read_entry(sbf_state_plan *plan, int i, PyObject *item, int *in_build)
{
    entry *e = &plan->entries[i];
    const char *code = py.PyTuple_Size(item) == 3 ? py.PyUnicode_AsUTF8(py.PyTuple_GetItem(item, 0)) : NULL;
    PyObject *argument = code ? py.PyTuple_GetItem(item, 2) : NULL;
    if (!code || (e->depth = read_path(py.PyTuple_GetItem(item, 1), e->path)) < 1) return 0;
    e->code = code[0];
    e->size = e->code == 'P' ? (long)py.PyLong_AsLongLong(argument) : field_size(e->code);
    int inside = *in_build > 0; /* a field of a section that builds its value: placed nowhere */
    e->parent = inside ? -1 : shape_of(plan, e->path, e->depth - 1);
    if (inside) --*in_build;
    if (e->code == 'm') {
        if (plan->names == MAX_NAMES) return 0;
        e->bit = plan->names++;
        py.Py_IncRef(e->object = argument);
    } else if (e->code == '[') {
        if (py.PyTuple_Size(argument) != 4 || !read_also(plan, i, e, py.PyTuple_GetItem(argument, 3))) return 0;
        e->flag = (int)py.PyLong_AsLongLong(py.PyTuple_GetItem(argument, 0));
        e->count = (int)py.PyLong_AsLongLong(py.PyTuple_GetItem(argument, 1));
        PyObject *build = py.PyTuple_GetItem(argument, 2);
        e->object = build == none ? NULL : build;
        if (e->object) {
            py.Py_IncRef(e->object);
            *in_build = e->count;
        }
        if (e->flag < 0 || e->flag >= i || e->count < 0 || i + e->count >= plan->n ||
            plan->entries[e->flag].code != 'n')
            return 0;
        if (plan->n_sections == MAX_SECTIONS) return 0;
        plan->sections[plan->n_sections++] = i;
        e->flag_at = plan->header_size;
        for (int k = 0; k < e->flag; ++k) { /* the flag's place is the sum of the sizes before it */
            if (plan->entries[k].size < 0) return 0;
            e->flag_at += (size_t)plan->entries[k].size;
        }
    }
    if (e->parent >= 0 && plan->shape_shared[e->parent] && e->size < 0) return 0; /* a shared shape's size is fixed */
    return e->size >= -1 && !py.PyErr_Occurred() && (inside || e->parent >= 0);
}

/* The plan's shapes and entries from its Python tuple (header, shapes, entries); 0 if malformed */
static int read_plan(sbf_state_plan *plan, PyObject *tuple)
{
    PyObject *header = py.PyTuple_Size(tuple) == 3 ? py.PyTuple_GetItem(tuple, 0) : NULL;
    PyObject *shapes = header ? py.PyTuple_GetItem(tuple, 1) : NULL, *entries = py.PyTuple_GetItem(tuple, 2);
    ptrdiff_t size = header ? py.PyBytes_Size(header) : -1, n_shapes = shapes ? py.PyTuple_Size(shapes) : -1;
    ptrdiff_t n = entries ? py.PyTuple_Size(entries) : -1;
    if (size < 0 || n_shapes < 1 || n_shapes > MAX_SHAPES || n < 1 || n > MAX_ENTRIES ||
        !(plan->header = malloc((size_t)size + 1)))
        return 0;
    memcpy(plan->header, py.PyBytes_AsString(header), (size_t)size);
    plan->header_size = (size_t)size;
    for (int s = 0; s < (int)n_shapes; ++s) {
        PyObject *shape = py.PyTuple_GetItem(shapes, s);
        if (py.PyTuple_Size(shape) != 3 || (plan->shape_depth[s] = read_path(py.PyTuple_GetItem(shape, 0),
                                                                           plan->shape_path[s])) < 0)
            return 0;
        plan->shape_length[s] = (ptrdiff_t)py.PyLong_AsLongLong(py.PyTuple_GetItem(shape, 1));
        plan->shape_shared[s] = py.PyTuple_GetItem(shape, 2) == yes;
        plan->n_shapes = s + 1;
        int outer = plan->shape_outer[s] = s > 0 ? shape_of(plan, plan->shape_path[s], plan->shape_depth[s] - 1) : -1;
        if (plan->shape_length[s] < 1 || plan->shape_length[s] > MAX_ITEMS || (s > 0 && outer < 0) ||
            (s == 0 && plan->shape_shared[s]) || (outer >= 0 && plan->shape_shared[outer]))
            return 0; /* the outermost shape first, each inside one before it; no shape in a shared one */
    }
    int in_build = 0;
    plan->n = (int)n;
    plan->first_name = -1;
    for (int i = 0; i < plan->n; ++i) {
        if (!read_entry(plan, i, py.PyTuple_GetItem(entries, i), &in_build)) return 0;
        if (plan->entries[i].code == 'm' && plan->first_name < 0) plan->first_name = i;
    }
    return plan->shape_depth[0] == 0;
}

sbf_state_plan *sbf_plan_new(void *slave)
{
    PyObject *tuple = resolved ? py.PyObject_GetAttrString(slave, "state_plan") : NULL;
    sbf_state_plan *plan = tuple ? calloc(1, sizeof *plan) : NULL;
    if (plan && !read_plan(plan, tuple)) {
        sbf_plan_free(plan);
        plan = NULL;
    }
    if (tuple) py.Py_DecRef(tuple);
    if (resolved) py.PyErr_Clear();
    return plan;
}

static void drop_part(part *p)
{
    if (p->object) py.Py_DecRef(p->object);
    free(p->bytes);
    *p = (part){0};
}

static void drop_template(sbf_state_plan *plan)
{
    if (plan->template) py.Py_DecRef(plan->template);
    free(plan->template_bytes);
    plan->template = NULL;
    plan->template_bytes = NULL;
}

void sbf_plan_free(sbf_state_plan *plan)
{
    if (!plan) return;
    for (int i = 0; i < plan->n; ++i) {
        if (plan->entries[i].object) py.Py_DecRef(plan->entries[i].object);
        drop_part(&plan->packed[i]);
    }
    for (int k = 0; k < 1 << MAX_NAMES; ++k)
        if (plan->pending[k]) py.Py_DecRef(plan->pending[k]);
    drop_template(plan);
    free(plan->header);
    free(plan->out);
    free(plan);
}

/* The value at path[0..depth) of `state` (borrowed), or NULL (a Python exception may be pending: an index out of
 * range, or a value on the way that is no tuple) */
static PyObject *value_at(PyObject *state, const ptrdiff_t *path, int depth)
{
    for (int k = 0; state && k < depth; ++k) state = py.PyTuple_GetItem(state, path[k]);
    return state;
}

/* ---- the layout of a state's bytes ---- */

/* Where each entry of bytes[0..size) lies (offset[i], and for "P" its size in sizes[i]; entries of an absent
 * section get offset SIZE_MAX), the part of any size taking `rest` bytes (-1: what the others leave); 1 if the
 * bytes have the plan's header, every flag of a section is 0 or 1 and they hold exactly the entries present. */
static int layout(const sbf_state_plan *plan, const unsigned char *bytes, size_t size, long rest, size_t *offset,
                  size_t *sizes)
{
    if (size < plan->header_size || memcmp(bytes, plan->header, plan->header_size) != 0) return 0;
    size_t at = plan->header_size, fixed = 0;
    int skip = 0, variable = -1;
    for (int i = 0; i < plan->n; ++i) { /* the flags lie before their sections: first pass for the fixed sizes */
        const entry *e = &plan->entries[i];
        if (skip > 0) {
            --skip;
            offset[i] = SIZE_MAX;
            continue;
        }
        offset[i] = 0;
        if (e->code == '[') {
            if (e->flag_at >= size || bytes[e->flag_at] > 1) return 0;
            if (!bytes[e->flag_at]) skip = e->count;
        } else if (e->size >= 0) {
            fixed += (size_t)e->size;
        } else if (variable >= 0) {
            return 0; /* one part of any size at most */
        } else {
            variable = i;
        }
    }
    if (size < plan->header_size + fixed) return 0;
    size_t left = size - plan->header_size - fixed;
    if (variable < 0 ? left != 0 : rest >= 0 && (size_t)rest != left) return 0;
    for (int i = 0; i < plan->n; ++i) {
        if (offset[i] == SIZE_MAX) continue;
        long n = i == variable ? (long)left : plan->entries[i].size;
        offset[i] = at;
        sizes[i] = (size_t)n;
        at += (size_t)n;
    }
    return 1;
}

/* ---- packing ---- */

/* The field `value` of entry `e` written at `out`; 0 if it is not of its kind */
static int pack_field(const entry *e, PyObject *value, unsigned char *out)
{
    double real = 0.0;
    long long number = 0;
    switch (e->code) {
    case 'd': case 'e':
        real = py.PyFloat_AsDouble(value);
        memcpy(out, &real, 8);
        return !(real == -1.0 && py.PyErr_Occurred());
    case 'q':
        number = py.PyLong_AsLongLong(value);
        memcpy(out, &number, 8);
        return !(number == -1 && py.PyErr_Occurred());
    case 'B': *out = value == yes; return value == yes || value == no;
    case 'b':
        number = py.PyLong_AsLongLong(value);
        *out = (unsigned char)(signed char)number;
        return number >= -128 && number <= 127 && !py.PyErr_Occurred();
    case 'o': case 's':
        *out = value != none;
        real = value == none ? 0.0 : py.PyFloat_AsDouble(value);
        memcpy(out + 1, &real, 8);
        return !(real == -1.0 && py.PyErr_Occurred());
    case 'n': *out = value != none; return 1;
    case 'm':
        number = py.PySequence_Contains(value, e->object);
        *out = (unsigned char)number;
        return number >= 0;
    }
    return 0;
}

/* Grow the plan's buffer to `size` bytes at least; 0 if out of memory */
static int out_room(sbf_state_plan *plan, size_t size)
{
    if (size <= plan->capacity) return 1;
    unsigned char *grown = realloc(plan->out, size);
    if (!grown) return 0;
    plan->out = grown;
    plan->capacity = size;
    return 1;
}

static long pack(sbf_state_plan *plan, PyObject *state, size_t room)
{
    unsigned char *out = plan->out;
    memcpy(out, plan->header, plan->header_size);
    size_t at = plan->header_size, where[MAX_ENTRIES];
    const entry *last = NULL; /* the entry before, whose tuple `holder` holds its value */
    PyObject *holder = NULL;
    for (int i = 0; i < plan->n; ++i) {
        const entry *e = &plan->entries[i];
        size_t up = sizeof *e->path * (size_t)(e->depth - 1);
        if (!last || last->depth != e->depth || memcmp(last->path, e->path, up) != 0)
            holder = value_at(state, e->path, e->depth - 1); /* entries of one tuple follow each other */
        last = e;
        PyObject *value = holder ? py.PyTuple_GetItem(holder, e->path[e->depth - 1]) : NULL;
        where[i] = at;
        if (!value) return -1;
        if (e->code == '[') {
            if (out[where[e->flag]] == 0) i += e->count;
            continue;
        }
        const part *p = &plan->packed[i];
        size_t n = e->code == 'P' ? p->size : (size_t)e->size;
        if (at + n > room || (e->code == 'P' ? value != p->object : !pack_field(e, value, out + at))) return -1;
        if (e->code == 'P') memcpy(out + at, p->bytes, n);
        at += n;
    }
    return (long)at;
}

long sbf_plan_pack(sbf_state_plan *plan, void *state, const unsigned char **bytes)
{
    size_t room = plan->header_size;
    for (int i = 0; i < plan->n; ++i) room += plan->entries[i].code == 'P' ? plan->packed[i].size
                                                                           : (size_t)plan->entries[i].size;
    long size = out_room(plan, room) ? pack(plan, state, room) : -1;
    if (size < 0) py.PyErr_Clear();
    *bytes = plan->out;
    return size;
}

void sbf_plan_packed(sbf_state_plan *plan, void *state, const unsigned char *bytes, size_t size)
{
    size_t offset[MAX_ENTRIES], sizes[MAX_ENTRIES];
    int known = layout(plan, bytes, size, -1, offset, sizes);
    for (int i = 0; i < plan->n; ++i) {
        const entry *e = &plan->entries[i];
        if (e->code != 'P') continue;
        drop_part(&plan->packed[i]);
        PyObject *object = known && offset[i] != SIZE_MAX ? value_at(state, e->path, e->depth) : NULL;
        part *p = &plan->packed[i];
        if (object && (p->bytes = malloc(sizes[i] + 1))) {
            memcpy(p->bytes, bytes + offset[i], sizes[i]);
            p->size = sizes[i];
            py.Py_IncRef(p->object = object);
        }
    }
    py.PyErr_Clear();
}

/* ---- unpacking ---- */

/* The field of entry `e` at `in` as a new object, or NULL if it is not of its kind (Fields.unpack's checks) */
static PyObject *unpack_field(const entry *e, const unsigned char *in)
{
    double real;
    long long number;
    switch (e->code) {
    case 'd': case 'e':
        memcpy(&real, in, 8);
        return real - real == 0.0 || (e->code == 'e' && real == HUGE_VAL) ? py.PyFloat_FromDouble(real) : NULL;
    case 'q':
        memcpy(&number, in, 8);
        return number >= 0 ? py.PyLong_FromLongLong(number) : NULL;
    case 'B': case 'n': case 'm':
        if (*in > 1) return NULL;
        py.Py_IncRef(*in ? yes : no);
        return *in ? yes : no;
    case 'b':
        number = (signed char)*in;
        return number >= -1 && number <= 1 ? py.PyLong_FromLongLong(number) : NULL;
    case 'o': case 's':
        memcpy(&real, in + 1, 8);
        if (*in == 0 && real == 0.0) {
            py.Py_IncRef(none);
            return none;
        }
        return *in == 1 && real - real == 0.0 && (e->code == 'o' || real > 0.0) ? py.PyFloat_FromDouble(real) : NULL;
    }
    return NULL;
}

/* The frozenset of the names whose "m" flags are `bits` (borrowed), or NULL */
static PyObject *pending(sbf_state_plan *plan, unsigned bits)
{
    if (plan->pending[bits]) return plan->pending[bits];
    ptrdiff_t count = 0;
    for (int i = 0; i < plan->n; ++i) count += plan->entries[i].code == 'm' && bits >> plan->entries[i].bit & 1;
    PyObject *names = py.PyTuple_New(count);
    for (int i = 0, k = 0; names && i < plan->n; ++i) {
        const entry *e = &plan->entries[i];
        if (e->code != 'm' || !(bits >> e->bit & 1)) continue;
        py.Py_IncRef(e->object);
        py.PyTuple_SetItem(names, k++, e->object);
    }
    PyObject *set = names ? py.PyFrozenSet_New(names) : NULL;
    if (names) py.Py_DecRef(names);
    return plan->pending[bits] = set;
}

/* A state being unpacked: its tuples (the outermost first), the "m" flags set, the items placed in each tuple (a
 * bit each) */
typedef struct {
    PyObject *shapes[MAX_SHAPES];
    unsigned bits;
    uint64_t placed[MAX_SHAPES];
    unsigned shared; /* the shared shapes taken from the template, a bit each: their entries are not unpacked */
} unpacking;

/* `value` (a reference stolen) into its place, the item `index` of shape `s`; 0 if that fails */
static int place(unpacking *u, int s, ptrdiff_t index, PyObject *value)
{
    if (!value || py.PyTuple_SetItem(u->shapes[s], index, value) != 0) return 0;
    u->placed[s] |= (uint64_t)1 << index;
    return 1;
}

/* The values a section's build is called with: a free slot (for the callee's own use, as vectorcall allows), the
 * template's value, the section's fields' values, then those of its `also` (references held) */
typedef struct {
    PyObject *items[2 + MAX_ENTRIES + MAX_ALSO];
    int n; /* items[2..2+n) are held */
} arguments;

static void drop_arguments(arguments *a)
{
    while (a->n) py.Py_DecRef(a->items[2 + --a->n]);
}

/* The value of the section `e` from the values `a` (dropped) under the template: its build called with them (no
 * list or tuple made); NULL if refused */
static PyObject *built(sbf_state_plan *plan, const entry *e, arguments *a)
{
    a->items[1] = value_at(plan->template, e->path, e->depth);
    PyObject *value = a->items[1] ? py.PyObject_Vectorcall(e->object, a->items + 1,
                                                           (size_t)(1 + a->n) | VECTORCALL_ARGUMENTS_OFFSET, NULL)
                                  : NULL;
    drop_arguments(a);
    return value;
}

/* The values of the fields the section `e` takes after its own (its `also`, placed before it) into `a`; 0 if one
 * is missing */
static int add_also(const sbf_state_plan *plan, const entry *e, const unpacking *u, arguments *a)
{
    for (int j = 0; j < e->n_also; ++j) {
        const entry *f = &plan->entries[e->also[j]];
        PyObject *value = py.PyTuple_GetItem(u->shapes[f->parent], f->path[f->depth - 1]);
        if (!value) return 0;
        py.Py_IncRef(value);
        a->items[2 + a->n++] = value;
    }
    return 1;
}

/* The entries of bytes[at..] from entry i on, into their places in the state `u` (or, within a section that builds
 * its value, into the arguments `a`); the index of the last entry done, or -1 if refused */
static int unpack_entries(sbf_state_plan *plan, const unsigned char *bytes, const size_t *offset, unpacking *u,
                          int first, int last, arguments *a)
{
    for (int i = first; i <= last; ++i) {
        const entry *e = &plan->entries[i];
        PyObject *value;
        if (e->parent >= 0 && u->shared >> e->parent & 1) { /* the template's, as its bytes are */
            i += e->code == '[' ? e->count : 0;
            continue;
        }
        if (e->code == '[' && e->count > 0 && offset[i + 1] == SIZE_MAX) { /* an absent section: its value is None */
            py.Py_IncRef(none);
            if (!place(u, e->parent, e->path[e->depth - 1], none)) return -1;
            i += e->count;
            continue;
        }
        if (e->code == '[') {
            if (!e->object) continue; /* its part is its value */
            arguments inner;
            inner.n = 0; /* its items are written as they come (not cleared: that would take longer than the rest) */
            if (!py.PyObject_Vectorcall || unpack_entries(plan, bytes, offset, u, i + 1, i + e->count, &inner) < 0 ||
                inner.n != e->count - 1 || !add_also(plan, e, u, &inner)) { /* all but one part are fields */
                drop_arguments(&inner);
                return -1;
            }
            if (!place(u, e->parent, e->path[e->depth - 1], built(plan, e, &inner))) return -1;
            i += e->count;
            continue;
        }
        if (e->code == 'P') {
            const part *p = &plan->unpacked[i];
            if (!p->size || memcmp(bytes + offset[i], plan->template_bytes + p->offset, p->size) != 0) return -1;
            if (!a) {
                value = value_at(plan->template, e->path, e->depth);
                if (value) py.Py_IncRef(value);
                if (!place(u, e->parent, e->path[e->depth - 1], value)) return -1;
            }
            continue;
        }
        if (e->code == 'n' || e->code == 'm') { /* a flag that places nothing itself */
            unsigned char flag = bytes[offset[i]];
            if (flag > 1) return -1;
            u->bits |= (unsigned)(e->code == 'm' && flag) << e->bit;
            continue;
        }
        if (!(value = unpack_field(e, bytes + offset[i]))) return -1;
        if (a) {
            a->items[2 + a->n++] = value;
        } else if (!place(u, e->parent, e->path[e->depth - 1], value)) {
            return -1;
        }
    }
    return last;
}

/* 1 if the bytes of every entry of the shared shape `s` at `offset` are the template's (then so is its tuple, which
 * nothing changes) */
static int as_template(const sbf_state_plan *plan, int s, const unsigned char *bytes, const size_t *offset)
{
    for (int i = 0; i < plan->n; ++i) {
        const entry *e = &plan->entries[i];
        size_t there = plan->template_laid[i];
        if (e->parent != s) continue;
        if ((offset[i] == SIZE_MAX) != (there == SIZE_MAX)) return 0;
        if (offset[i] != SIZE_MAX && memcmp(bytes + offset[i], plan->template_bytes + there, (size_t)e->size) != 0)
            return 0;
    }
    return 1;
}

/* The state's tuples, the inner ones in their places in the outer, a shared one as the template's where its bytes
 * are (u->shared); NULL if out of memory */
static PyObject *new_shapes(const sbf_state_plan *plan, const unsigned char *bytes, const size_t *offset,
                            unpacking *u)
{
    for (int s = 0; s < plan->n_shapes; ++s) {
        PyObject *shared = plan->shape_shared[s] && as_template(plan, s, bytes, offset)
                               ? value_at(plan->template, plan->shape_path[s], plan->shape_depth[s]) : NULL;
        if (shared) {
            py.Py_IncRef(shared);
            u->shared |= 1u << s;
        }
        u->shapes[s] = shared ? shared : py.PyTuple_New(plan->shape_length[s]);
        int ok = u->shapes[s] != NULL;
        if (ok && s > 0) {
            ok = place(u, plan->shape_outer[s], plan->shape_path[s][plan->shape_depth[s] - 1], u->shapes[s]);
        }
        if (!ok) {
            if (s > 0 || u->shapes[0]) py.Py_DecRef(u->shapes[0]);
            return NULL;
        }
    }
    return u->shapes[0];
}

/* Where each entry of bytes[0..size) lies (layout's offsets), the part of any size as big as the template's: the
 * layout of the bytes unpacked last again where they are as long and have the same sections (the offsets follow
 * from those alone), else laid out anew; NULL if the bytes do not fit the plan. */
static const size_t *laid_out(sbf_state_plan *plan, const unsigned char *bytes, size_t size)
{
    if (size < plan->header_size || memcmp(bytes, plan->header, plan->header_size) != 0) return NULL;
    unsigned sections = 0;
    for (int k = 0; k < plan->n_sections; ++k) {
        size_t at = plan->entries[plan->sections[k]].flag_at;
        if (at >= size || bytes[at] > 1) return NULL;
        sections |= (unsigned)bytes[at] << k;
    }
    if (size == plan->laid_size && sections == plan->laid_sections) return plan->laid;
    size_t sizes[MAX_ENTRIES];
    long rest = -1;
    for (int i = 0; i < plan->n; ++i)
        if (plan->entries[i].size < 0) rest = (long)plan->unpacked[i].size;
    int fits = layout(plan, bytes, size, rest, plan->laid, sizes);
    plan->laid_size = fits ? size : 0;
    plan->laid_sections = sections;
    return fits ? plan->laid : NULL;
}

static PyObject *unpack(sbf_state_plan *plan, const unsigned char *bytes, size_t size)
{
    const size_t *offset = plan->template ? laid_out(plan, bytes, size) : NULL;
    unpacking u = {.bits = 0};
    if (!offset || !new_shapes(plan, bytes, offset, &u)) return NULL;
    int done = unpack_entries(plan, bytes, offset, &u, 0, plan->n - 1, NULL) == plan->n - 1;
    if (done && plan->first_name >= 0) { /* the names of the "m" flags: one frozenset */
        const entry *e = &plan->entries[plan->first_name];
        PyObject *set = pending(plan, u.bits);
        if (set) py.Py_IncRef(set);
        done = place(&u, e->parent, e->path[e->depth - 1], set);
    }
    for (int s = 0; done && s < plan->n_shapes; ++s) /* every item placed */
        done = u.shared >> s & 1 || u.placed[s] == (plan->shape_length[s] == MAX_ITEMS ? ~(uint64_t)0
                                                                   : ((uint64_t)1 << plan->shape_length[s]) - 1);
    if (!done) {
        py.Py_DecRef(u.shapes[0]);
        return NULL;
    }
    return u.shapes[0];
}

void *sbf_plan_unpack(sbf_state_plan *plan, const unsigned char *bytes, size_t size)
{
    PyObject *state = unpack(plan, bytes, size);
    if (!state) py.PyErr_Clear();
    return state;
}

void sbf_plan_unpacked(sbf_state_plan *plan, void *state, const unsigned char *bytes, size_t size)
{
    size_t offset[MAX_ENTRIES], sizes[MAX_ENTRIES];
    drop_template(plan);
    memset(plan->unpacked, 0, sizeof plan->unpacked);
    plan->laid_size = 0; /* the part of any size may differ */
    if (!layout(plan, bytes, size, -1, offset, sizes) || !(plan->template_bytes = malloc(size + 1))) return;
    memcpy(plan->template_bytes, bytes, size);
    memcpy(plan->template_laid, offset, sizeof offset);
    plan->template_size = size;
    py.Py_IncRef(plan->template = state);
    for (int i = 0; i < plan->n; ++i)
        if (plan->entries[i].code == 'P' && offset[i] != SIZE_MAX)
            plan->unpacked[i] = (part){.offset = offset[i], .size = sizes[i]};
}
