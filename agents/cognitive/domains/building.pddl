; The IntellWheels building domain: a chair moves between places; doors must be open to pass,
; and a locked door (restricted area, door agent refusal) cannot be opened.
(define (domain building)
  (:requirements :strips :typing :negative-preconditions)
  (:types chair place door)
  (:predicates (at ?c - chair ?p - place)
               (connected ?a ?b - place)
               (through ?a ?b - place ?d - door)
               (open ?d - door)
               (locked ?d - door))
  (:action move
    :parameters (?c - chair ?from ?to - place)
    :precondition (and (at ?c ?from) (connected ?from ?to))
    :effect (and (not (at ?c ?from)) (at ?c ?to)))
  (:action open-door
    :parameters (?c - chair ?from ?to - place ?d - door)
    :precondition (and (at ?c ?from) (through ?from ?to ?d) (not (open ?d)) (not (locked ?d)))
    :effect (open ?d))
  (:action pass-door
    :parameters (?c - chair ?from ?to - place ?d - door)
    :precondition (and (at ?c ?from) (through ?from ?to ?d) (open ?d))
    :effect (and (not (at ?c ?from)) (at ?c ?to))))
