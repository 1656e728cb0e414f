/* A frame's /parts and /foxglove/transforms messages from orjson's text of their numbers.

   ``codec.FrameEncoder`` writes the numbers of the parts a frame shows with one
   ``orjson.dumps`` (shortest digits, Ryu) and hands the text here with the parts' quoted
   names and modes; this cuts the numbers apart, puts each in ``json``'s notation and writes
   both messages around them. The same function in Python is ``codec._frame_json_py``, the
   reference this is held to bit for bit (``tests/test_codec.py``); where a number is not in
   a form handled here, or the text is not as expected, the result is None and the caller
   writes the frame the slower way. No Python object is made per number, which is where
   the Python writer spent its time (a list of texts split, rejoined by f-strings).

   The notation: orjson writes a float as ``repr`` does (``json``'s text of it) except
     d.ddde-N   (a one-digit negative exponent)        repr: d.ddde-0N
     d.ddde16   (a positive exponent without its sign)   repr: d.ddde+16
     0.0000ddd  (1e-5 <= |x| < 1e-4)                   repr: d.dde-05
   A negative exponent of two or three digits, and a signed positive one (as orjson 3.13
   writes it), are written alike. Tokens are taken only as
   [-+0-9.e] with one dot: "null" (orjson's NaN and infinity, which json refuses), true,
   false, exponents of other forms and anything else give None, for the Python writer. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <string.h>

#define NUMBERS_PER_PART 13

typedef struct {
    Py_ssize_t at;  /* offset in the scratch buffer */
    Py_ssize_t n;   /* length */
} token;

static int
all_digits(const char *p, Py_ssize_t n)
{
    for (Py_ssize_t i = 0; i < n; i++)
        if (p[i] < '0' || p[i] > '9')
            return 0;
    return 1;
}

/* json's text of one orjson number token t[0:n] into out (room for n + 4); its length, or
   -1 where this does not cover it. */
static Py_ssize_t
json_number(const char *t, Py_ssize_t n, char *out)
{
    Py_ssize_t i, sign = 0, bn, dot = -1, dots = 0;
    const char *body = t;
    int has_e = 0;
    if (n > 0 && t[0] == '-') {
        sign = 1;
        body = t + 1;
    }
    bn = n - sign;
    if (bn <= 0)
        return -1;
    for (i = 0; i < bn; i++) {
        char c = body[i];
        if (c >= '0' && c <= '9')
            continue;
        if (c == '.') {
            dot = i;
            dots++;
        } else if (c == 'e') {
            has_e = 1;
        } else if (c != '-' && c != '+') {
            return -1;
        }
    }
    if (dots > 1)
        return -1;
    if (has_e) {
        const char *e = memchr(body, 'e', (size_t)bn);
        Py_ssize_t at = e - body, digits = bn - at - 1;  /* after the e */
        if (at < 1 || memchr(e + 1, 'e', (size_t)digits) != NULL || digits < 1)
            return -1;
        if (e[1] == '-') {
            digits--;
            if (!all_digits(e + 2, digits))
                return -1;
            if (digits == 1 && e[2] >= '1') {
                /* d.ddde-N: insert the 0 repr writes. */
                memcpy(out, t, (size_t)(n - 1));
                out[n - 1] = '0';
                out[n] = t[n - 1];
                return n + 1;
            }
            if ((digits == 2 || digits == 3) && e[2] >= '1') {
                memcpy(out, t, (size_t)n);  /* e-NN, e-NNN: repr's own */
                return n;
            }
            return -1;
        }
        if (e[1] == '+') {
            /* d.ddde+16, as orjson 3.13 writes it: repr's own. */
            digits--;
            if (!all_digits(e + 2, digits))
                return -1;
            if ((digits == 2 || digits == 3) && e[2] >= '1') {
                memcpy(out, t, (size_t)n);
                return n;
            }
            return -1;
        }
        if (!all_digits(e + 1, digits))
            return -1;
        if ((digits == 2 || digits == 3) && e[1] >= '1') {
            /* d.ddde16: repr writes e+16. */
            Py_ssize_t k = sign + at + 1;
            memcpy(out, t, (size_t)k);
            out[k] = '+';
            memcpy(out + k + 1, t + k, (size_t)(n - k));
            return n + 1;
        }
        return -1;
    }
    /* "0.0000" (with the one dot): only 0.0000d... (d nonzero) is rewritten, d.ddd e-05;
       an integer part ending in 0 (10.00001) is json's notation too, a leading zero
       (00.00001) no number orjson writes. */
    if (dot >= 1 && body[dot - 1] == '0' && bn - dot >= 5
            && memcmp(body + dot + 1, "0000", 4) == 0) {
        Py_ssize_t k = 0, digits = bn - 6;
        if (dot != 1) {
            if (body[0] == '0')
                return -1;
            memcpy(out, t, (size_t)n);
            return n;
        }
        if (digits < 1 || body[6] == '0' || !all_digits(body + 6, digits))
            return -1;
        if (sign)
            out[k++] = '-';
        out[k++] = body[6];
        if (digits > 1) {
            out[k++] = '.';
            memcpy(out + k, body + 7, (size_t)(digits - 1));
            k += digits - 1;
        }
        memcpy(out + k, "e-05", 4);
        return k + 4;
    }
    memcpy(out, t, (size_t)n);
    return n;
}

/* The writer: a cursor into the output, or a counter of its length (out == NULL). */
typedef struct {
    char *out;
    Py_ssize_t n;
} writer;

static inline void
put(writer *w, const char *s, Py_ssize_t n)
{
    if (w->out)
        memcpy(w->out + w->n, s, (size_t)n);
    w->n += n;
}

#define PUT(w, lit) put((w), (lit), (Py_ssize_t)(sizeof(lit) - 1))

/* A non-negative integer in decimal, as "%llu" writes it (snprintf was a quarter of this
   module's instructions a frame, for three integers). */
static void
put_decimal(writer *w, unsigned long long v)
{
    char digits[20];  /* 2**64 - 1 has 20 */
    Py_ssize_t k = 20;
    do {
        digits[--k] = (char)('0' + (int)(v % 10));
        v /= 10;
    } while (v);
    put(w, digits + k, 20 - k);
}

static inline void
put_bytes(writer *w, PyObject *b)
{
    put(w, PyBytes_AS_STRING(b), PyBytes_GET_SIZE(b));
}

static inline void
put_token(writer *w, const char *scratch, const token *tokens, Py_ssize_t i)
{
    put(w, scratch + tokens[i].at, tokens[i].n);
}

static void
write_part(writer *w, const char *s, const token *tk, PyObject *name, PyObject *mode)
{
    /* {"angular_velocity":[0,1,2],"linear_velocity":[3,4,5],"mode":M,"name":N,
        "position":[6,7,8],"xyzw":[9,10,11,12]} */
    PUT(w, "{\"angular_velocity\":[");
    put_token(w, s, tk, 0); PUT(w, ","); put_token(w, s, tk, 1); PUT(w, ",");
    put_token(w, s, tk, 2);
    PUT(w, "],\"linear_velocity\":[");
    put_token(w, s, tk, 3); PUT(w, ","); put_token(w, s, tk, 4); PUT(w, ",");
    put_token(w, s, tk, 5);
    PUT(w, "],\"mode\":");
    put_bytes(w, mode);
    PUT(w, ",\"name\":");
    put_bytes(w, name);
    PUT(w, ",\"position\":[");
    put_token(w, s, tk, 6); PUT(w, ","); put_token(w, s, tk, 7); PUT(w, ",");
    put_token(w, s, tk, 8);
    PUT(w, "],\"xyzw\":[");
    put_token(w, s, tk, 9); PUT(w, ","); put_token(w, s, tk, 10); PUT(w, ",");
    put_token(w, s, tk, 11); PUT(w, ","); put_token(w, s, tk, 12);
    PUT(w, "]}");
}

static void
write_transform(writer *w, const char *s, const token *tk, PyObject *name, const char *stamp,
                Py_ssize_t stamp_n)
{
    /* {"child_frame_id":N,"parent_frame_id":"world","rotation":{"w":12,"x":9,"y":10,
        "z":11},"timestamp":STAMP,"translation":{"x":6,"y":7,"z":8}} */
    PUT(w, "{\"child_frame_id\":");
    put_bytes(w, name);
    PUT(w, ",\"parent_frame_id\":\"world\",\"rotation\":{\"w\":");
    put_token(w, s, tk, 12); PUT(w, ",\"x\":"); put_token(w, s, tk, 9);
    PUT(w, ",\"y\":"); put_token(w, s, tk, 10); PUT(w, ",\"z\":"); put_token(w, s, tk, 11);
    PUT(w, "},\"timestamp\":");
    put(w, stamp, stamp_n);
    PUT(w, ",\"translation\":{\"x\":");
    put_token(w, s, tk, 6); PUT(w, ",\"y\":"); put_token(w, s, tk, 7);
    PUT(w, ",\"z\":"); put_token(w, s, tk, 8);
    PUT(w, "}}");
}

/* The frame's own texts around its parts: what /parts has between the base and the first
   part's object (up to and with the "[" of "parts"), after the last part's, and the
   transforms' timestamp object. */
typedef struct {
    char middle[64];
    Py_ssize_t middle_n;
    char end[48];
    Py_ssize_t end_n;
    char stamp[64];
    Py_ssize_t stamp_n;
} frame_texts;

static void
write_messages(writer *parts, writer *transforms, const char *scratch, const token *tokens,
               PyObject *names, PyObject *modes, int with_base, const frame_texts *ft)
{
    Py_ssize_t k = PyList_GET_SIZE(names), i;
    PUT(parts, "{\"base\":");
    if (with_base)
        write_part(parts, scratch, tokens, PyList_GET_ITEM(names, 0),
                   PyList_GET_ITEM(modes, 0));
    else
        PUT(parts, "null");
    put(parts, ft->middle, ft->middle_n);
    for (i = with_base ? 1 : 0; i < k; i++) {
        if (i > (with_base ? 1 : 0))
            PUT(parts, ",");
        write_part(parts, scratch, tokens + NUMBERS_PER_PART * i, PyList_GET_ITEM(names, i),
                   PyList_GET_ITEM(modes, i));
    }
    put(parts, ft->end, ft->end_n);
    PUT(transforms, "{\"transforms\":[");
    for (i = 0; i < k; i++) {
        if (i > 0)
            PUT(transforms, ",");
        write_transform(transforms, scratch, tokens + NUMBERS_PER_PART * i,
                        PyList_GET_ITEM(names, i), ft->stamp, ft->stamp_n);
    }
    PUT(transforms, "]}");
}

static int
all_bytes(PyObject *list)
{
    for (Py_ssize_t i = 0; i < PyList_GET_SIZE(list); i++)
        if (!PyBytes_CheckExact(PyList_GET_ITEM(list, i)))
            return 0;
    return 1;
}

/* The frame's texts from its frame number, time and "complete" (0: none, the full
   encoding's frames; 1: false; 2: true); 0, or -1 where frame or time is not a
   non-negative integer of 64 bits (the caller then writes the frame the slower way). */
static int
make_frame_texts(frame_texts *ft, PyObject *complete_obj, PyObject *frame_obj,
                 PyObject *time_obj)
{
    static const char *completes[] = {"", ",\"complete\":false", ",\"complete\":true"};
    long complete;
    long long frame;
    unsigned long long t;
    if (!PyLong_CheckExact(complete_obj) || !PyLong_CheckExact(frame_obj)
            || !PyLong_CheckExact(time_obj))
        return -1;
    complete = PyLong_AsLong(complete_obj);
    if (PyErr_Occurred() || complete < 0 || complete > 2) {  /* (each checked before the
                                                                next call: the C API) */
        PyErr_Clear();
        return -1;
    }
    frame = PyLong_AsLongLong(frame_obj);
    if (PyErr_Occurred() || frame < 0) {
        PyErr_Clear();
        return -1;
    }
    t = PyLong_AsUnsignedLongLong(time_obj);
    if (PyErr_Occurred()) {  /* negative, or past 64 bits */
        PyErr_Clear();
        return -1;
    }
    {
        writer w = {ft->middle, 0};
        put(&w, completes[complete], (Py_ssize_t)strlen(completes[complete]));
        PUT(&w, ",\"frame\":");
        put_decimal(&w, (unsigned long long)frame);
        PUT(&w, ",\"parts\":[");
        ft->middle_n = w.n;
    }
    {
        writer w = {ft->end, 0};
        PUT(&w, "],\"time_ns\":");
        put_decimal(&w, t);
        PUT(&w, "}");
        ft->end_n = w.n;
    }
    {
        writer w = {ft->stamp, 0};
        PUT(&w, "{\"nsec\":");
        put_decimal(&w, t % 1000000000ULL);
        PUT(&w, ",\"sec\":");
        put_decimal(&w, t / 1000000000ULL);
        PUT(&w, "}");
        ft->stamp_n = w.n;
    }
    return 0;
}

/* frame_messages(numbers, names, modes, with_base, complete, frame, time_ns)
     -> (parts, transforms) | None

   numbers: orjson's text of a list of 13 numbers a part shown (angular velocity, linear
   velocity, position, rotation xyzw), the base's first where with_base; names and modes:
   lists of bytes, each part's quoted as json quotes it; complete: 0 (the full encoding:
   no "complete" key), 1 (false) or 2 (true); frame and time_ns: the frame's number and
   time (non-negative integers of 64 bits). */
static PyObject *
frame_messages(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    PyObject *numbers, *names, *modes, *result = Py_None;
    Py_ssize_t k, count, n, i, start, expected;
    const char *text;
    char *scratch = NULL;
    token *tokens = NULL;
    frame_texts ft;
    int with_base;
    if (nargs != 7) {
        PyErr_SetString(PyExc_TypeError, "frame_messages takes 7 arguments");
        return NULL;
    }
    numbers = args[0]; names = args[1]; modes = args[2];
    with_base = PyObject_IsTrue(args[3]);
    if (with_base < 0)
        return NULL;
    if (!PyBytes_CheckExact(numbers) || !PyList_CheckExact(names)
            || !PyList_CheckExact(modes)) {
        PyErr_SetString(PyExc_TypeError, "frame_messages: bytes and lists of bytes expected");
        return NULL;
    }
    k = PyList_GET_SIZE(names);
    if (PyList_GET_SIZE(modes) != k || !all_bytes(names) || !all_bytes(modes)) {
        PyErr_SetString(PyExc_TypeError, "frame_messages: names and modes: bytes, as many");
        return NULL;
    }
    if (k == 0 || make_frame_texts(&ft, args[4], args[5], args[6]) < 0)
        Py_RETURN_NONE;
    expected = NUMBERS_PER_PART * k;
    text = PyBytes_AS_STRING(numbers);
    n = PyBytes_GET_SIZE(numbers);
    if (n < 2 || text[0] != '[' || text[n - 1] != ']')
        Py_RETURN_NONE;
    tokens = PyMem_Malloc(sizeof(token) * (size_t)expected);
    /* Each token grows by at most 4 bytes ("0.0000d" -> "de-05" shrinks; "e-N" +1). */
    scratch = PyMem_Malloc((size_t)(n + 4 * expected + 8));
    if (tokens == NULL || scratch == NULL) {
        PyMem_Free(tokens);
        PyMem_Free(scratch);
        return PyErr_NoMemory();
    }
    {
        Py_ssize_t at = 0, len;
        count = 0;
        start = 1;
        while (start <= n - 1) {
            const char *comma = memchr(text + start, ',', (size_t)(n - 1 - start));
            i = comma == NULL ? n - 1 : comma - text;  /* the token's end: "," or "]" */
            if (count >= expected)
                goto none;
            len = json_number(text + start, i - start, scratch + at);
            if (len < 0)
                goto none;
            tokens[count].at = at;
            tokens[count].n = len;
            at += len;
            count++;
            start = i + 1;
        }
        if (count != expected)
            goto none;
    }
    {
        writer pc = {NULL, 0}, tc = {NULL, 0};
        PyObject *parts, *transforms;
        write_messages(&pc, &tc, scratch, tokens, names, modes, with_base, &ft);
        parts = PyBytes_FromStringAndSize(NULL, pc.n);
        transforms = PyBytes_FromStringAndSize(NULL, tc.n);
        if (parts == NULL || transforms == NULL) {
            Py_XDECREF(parts);
            Py_XDECREF(transforms);
            result = NULL;
            goto done;
        }
        {
            writer pw = {PyBytes_AS_STRING(parts), 0}, tw = {PyBytes_AS_STRING(transforms), 0};
            write_messages(&pw, &tw, scratch, tokens, names, modes, with_base, &ft);
        }
        result = PyTuple_Pack(2, parts, transforms);
        Py_DECREF(parts);
        Py_DECREF(transforms);
        goto done;
    }
none:
    result = Py_None;
    Py_INCREF(result);
done:
    PyMem_Free(tokens);
    PyMem_Free(scratch);
    return result;
}

static PyMethodDef methods[] = {
    {"frame_messages", (PyCFunction)(void (*)(void))frame_messages, METH_FASTCALL,
     "A frame's /parts and /foxglove/transforms bytes from orjson's text of their numbers, "
     "or None (see codec._frame_json_py)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "vade_replay._framejson",
    "A frame's messages written around orjson's numbers (codec.FrameEncoder).", -1, methods,
};

PyMODINIT_FUNC
PyInit__framejson(void)
{
    return PyModule_Create(&module);
}
