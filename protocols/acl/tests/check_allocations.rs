//! `codec::check_with` allocates nothing for the messages the bus carries: counted by a global
//! allocator, on this thread only.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use iw_acl::codec::{self, ParseOptions};

struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

// SAFETY: every call is forwarded to the system allocator unchanged; the counters are
// const-initialized thread-locals without destructors, so touching them never allocates.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.with(|n| n.set(n.get() + 1));
        }
        // SAFETY: the caller's contract is passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract is passed on.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.with(|n| n.set(n.get() + 1));
        }
        // SAFETY: the caller's contract is passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Allocations made by `f` on this thread.
fn allocations<T>(f: impl FnOnce() -> T) -> (usize, T) {
    ALLOCATIONS.with(|n| n.set(0));
    COUNTING.with(|c| c.set(true));
    let out = f();
    COUNTING.with(|c| c.set(false));
    (ALLOCATIONS.with(Cell::get), out)
}

#[test]
fn typical_messages_are_checked_without_allocating() {
    let content = "x".repeat(120);
    let texts = [
        format!(
            "(request :sender (agent-identifier :name ping) :receiver (set (agent-identifier :name echo)) \
             :language fipa-sl :ontology wheelchair :conversation-id bench :content \"{content}\")"
        ),
        "(INFORM\n :sender (agent-identifier :name localization@IntellWheels :addresses (sequence http://10.0.0.2:7778/acc))\n \
         :receiver (set (agent-identifier :name planner@IntellWheels) (agent-identifier :name logger@IntellWheels))\n \
         :content \"((= (iota ?p (pose wheelchair1 ?p)) (pose :x 3.25 :y -1.5 :theta \\\"0.785\\\")))\"\n \
         :reply-by 20991231T235959000Z :X-battery 87 :x-seq \"4\" :protocol fipa-query\n \
         :conversation-id conv-4711 :in-reply-to q-4711)"
            .to_owned(),
        "(inform :sender (agent-identifier :name a :resolvers (sequence (agent-identifier :name r :X-k 1))) \
         :X-JADE-Encoding Base64 :content \"AAEC/yJc\" :reply-to (set (agent-identifier :name \"q\\\"uoted\")))"
            .to_owned(),
    ];
    for options in [ParseOptions::default(), ParseOptions::jade()] {
        for text in &texts {
            let (count, summary) = allocations(|| {
                codec::check_with(text, &options)
                    .map(|s| (s.sender().map(str::len), s.receiver_count()))
            });
            assert!(summary.is_ok(), "{summary:?}: {text}");
            assert_eq!(count, 0, "{text}");
            let (parse_count, _) = allocations(|| codec::parse_with(text, &options));
            assert!(parse_count > 0, "the counter counts");
        }
    }
}
