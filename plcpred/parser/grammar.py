"""LALR grammars (lark) for Structured Text and for the ``.seq`` sequence-chart format.

Tokens come from :mod:`plcpred.parser.lexer`; names starting with ``_`` are filtered from
the parse tree. Two choices keep the grammar LALR(1) and fast:

* Expressions are parsed flat (``operand (binop operand)*``) and the transformer applies
  IEC 61131-3 precedence (ed.3 table 71; the B.3.1 productions of ed.2 agree): unary
  ``-``/``+``/``NOT`` bind tighter than ``**``, then ``* / MOD``, ``+ -``, ``< > <= >=``,
  ``= <>``, ``AND & AND_THEN``, ``XOR``, ``OR OR_ELSE``, all left-associative.
* CASE bodies are flat lists of labels and statements that the transformer groups, which
  avoids the one-token-lookahead clash between an enum label ``Idle:`` and a statement.
"""

TERMINALS = """
%declare INLINE_CODE NAME INTEGER REAL TYPED_LIT TIME_LIT DT_LIT TOD_LIT DATE_LIT ENUM_LIT STRING_LIT WSTRING_LIT ADDRESS
%declare _ASSIGN _OUTASSIGN LE GE NE POW _DOTDOT _ATTEMPT PLUS MINUS STAR SLASH LT GT EQ _LPAR _RPAR _LSQB _RSQB _COMMA _SEMI _COLON _DOT _CARET AMP _ARROW _REFASSIGN _SETASSIGN _RESETASSIGN
%declare PROGRAM _END_PROGRAM FUNCTION _END_FUNCTION FUNCTION_BLOCK _END_FUNCTION_BLOCK METHOD _END_METHOD
%declare PROPERTY _END_PROPERTY INTERFACE _END_INTERFACE _EXTENDS _IMPLEMENTS END_GET END_SET
%declare VAR VAR_INPUT VAR_OUTPUT VAR_IN_OUT VAR_TEMP VAR_GLOBAL VAR_EXTERNAL VAR_STAT VAR_INST VAR_CONFIG VAR_ACCESS VAR_GENERIC _END_VAR
%declare CONSTANT RETAIN NON_RETAIN PERSISTENT _AT
%declare TYPE _END_TYPE STRUCT _END_STRUCT UNION _END_UNION _ARRAY _OF POINTER REFERENCE REF_TO _TO STRING WSTRING
%declare IF _THEN _ELSIF _ELSE _END_IF CASE _END_CASE FOR _BY _DO _END_FOR WHILE _END_WHILE REPEAT _UNTIL _END_REPEAT
%declare EXIT CONTINUE RETURN JMP AND OR XOR NOT MOD AND_THEN OR_ELSE TRUE FALSE
%declare CONFIGURATION _END_CONFIGURATION RESOURCE _END_RESOURCE TASK
%declare PUBLIC PRIVATE PROTECTED INTERNAL ABSTRACT FINAL CLASS _END_CLASS
%declare INITIAL_STEP STEP _END_STEP TRANSITION _FROM _END_TRANSITION ACTION _END_ACTION
%declare TRY _CATCH CATCH_VAR _FINALLY _ENDTRY
"""

COMMON = r"""
// ------------------------------------------------------------------ expressions
?expr: operand (binop operand)*
?binop: PLUS | MINUS | STAR | SLASH | POW | MOD | LT | GT | LE | GE | EQ | NE
      | AND | AMP | AND_THEN | XOR | OR | OR_ELSE

?operand: postfix
        | MINUS operand -> neg
        | PLUS operand -> plus
        | NOT operand -> not_

?postfix: atom
        | postfix _DOT NAME -> member
        | postfix _DOT INTEGER -> bit_access
        | postfix _LSQB expr (_COMMA expr)* _RSQB -> index
        | postfix _CARET -> deref
        | postfix _LPAR [args] _RPAR -> call
        | postfix _LPAR POINTER _TO type_spec [_COMMA expr] _RPAR -> new_pointers
        | postfix _LPAR string_kw [string_len] [_COMMA expr] _RPAR -> new_string

?atom: NAME -> name
     | ADDRESS -> address
     | INTEGER -> int_lit
     | REAL -> real_lit
     | TYPED_LIT -> typed_lit
     | TIME_LIT -> time_lit
     | DT_LIT -> time_lit
     | TOD_LIT -> time_lit
     | DATE_LIT -> time_lit
     | STRING_LIT -> string_lit
     | WSTRING_LIT -> string_lit
     | TRUE -> bool_lit
     | FALSE -> bool_lit
     | ENUM_LIT -> enum_lit
     | _LPAR expr _RPAR
     | _LPAR postfix _ASSIGN expr _RPAR -> assign_expr
     | fn_operator _LPAR args _RPAR -> operator_call
// the operators IEC also defines as functions, called as such: AND(a, b), MOD(a, b)
!fn_operator: AND | OR | XOR | MOD

args: arg (_COMMA arg)* _COMMA?
?arg: expr -> pos_arg
    | NAME _ASSIGN [expr] -> named_arg
    | NAME _OUTASSIGN [postfix] -> out_arg
    | NOT NAME _OUTASSIGN [postfix] -> neg_out_arg

// ------------------------------------------------------------------ statements
stmt_list: stmt*
?stmt: assign | ref_assign | set_assign | reset_assign | attempt_assign | call_stmt | if_stmt | case_stmt | for_stmt
     | while_stmt | repeat_stmt | exit_stmt | continue_stmt | return_stmt | empty_stmt
     | jmp_stmt | label_stmt | inline_stmt | try_stmt
?stmt_nolabel: assign | ref_assign | set_assign | reset_assign | attempt_assign | call_stmt | if_stmt | case_stmt
             | for_stmt | while_stmt | repeat_stmt | exit_stmt | continue_stmt | return_stmt
             | empty_stmt | jmp_stmt | inline_stmt | try_stmt

assign: postfix _ASSIGN expr _SEMI
      | postfix _ASSIGN postfix _ASSIGN expr _SEMI -> chained_assign
ref_assign: postfix _REFASSIGN expr _SEMI
set_assign: postfix _SETASSIGN expr _SEMI
reset_assign: postfix _RESETASSIGN expr _SEMI
attempt_assign: postfix _ATTEMPT expr _SEMI
call_stmt: postfix _SEMI
if_stmt: IF condition _THEN stmt_list elsif* [_ELSE stmt_list] _END_IF
elsif: _ELSIF condition _THEN stmt_list
// TwinCAT accepts an assignment as the condition: IF ok := Start() THEN
?condition: expr
          | postfix _ASSIGN expr -> assign_expr
case_stmt: CASE expr _OF case_part* [_ELSE stmt_list] _END_CASE
?case_part: case_head | stmt_nolabel
case_head: case_label (_COMMA case_label)* _COLON
?case_label: expr
           | expr _DOTDOT expr -> case_range
for_stmt: FOR postfix _ASSIGN expr _TO expr [_BY expr] _DO stmt_list _END_FOR
while_stmt: WHILE expr _DO stmt_list _END_WHILE
repeat_stmt: REPEAT stmt_list _UNTIL expr _END_REPEAT
exit_stmt: EXIT _SEMI
continue_stmt: CONTINUE _SEMI
return_stmt: RETURN _SEMI
           | RETURN _LPAR expr _RPAR _SEMI -> conditional_return
           | RETURN _LPAR postfix _ASSIGN expr _RPAR _SEMI -> conditional_return_assign
empty_stmt: _SEMI
jmp_stmt: JMP NAME _SEMI
label_stmt: NAME _COLON
inline_stmt: INLINE_CODE
// CODESYS/TwinCAT: __TRY ... __CATCH(exc) ... __FINALLY ... __ENDTRY
try_stmt: TRY stmt_list [catch_part] [_FINALLY stmt_list] _ENDTRY
catch_part: _CATCH stmt_list -> catch_plain
          | CATCH_VAR stmt_list -> catch_var

// ------------------------------------------------------------------ types and declarations
qual_name: NAME (_DOT NAME)*
name_list: NAME (_COMMA NAME)*

?type_spec: qual_name -> named_type
          | STRING [string_len] -> string_type
          | WSTRING [string_len] -> string_type
          | _ARRAY _LSQB array_dim (_COMMA array_dim)* _RSQB _OF type_spec -> array_type
          | POINTER _TO type_spec -> pointer_type
          | REFERENCE _TO type_spec -> pointer_type
          | REF_TO type_spec -> pointer_type
          | qual_name _LPAR expr _DOTDOT expr _RPAR -> subrange_type
          | qual_name _LPAR [args] _RPAR -> fb_init_type
          | qual_name _LSQB fb_init_args (_COMMA fb_init_args)* _RSQB -> fb_init_list_type
          | qual_name LT generic_arg (_COMMA generic_arg)* GT -> generic_type
          | qual_name LT generic_arg (_COMMA generic_arg)* GT _LPAR [args] _RPAR -> generic_fb_init_type
          | _LPAR enum_value (_COMMA enum_value)* _RPAR [NAME] -> enum_type
          | STRUCT var_decl* _END_STRUCT -> struct_type
          | UNION var_decl* _END_UNION -> struct_type
?string_len: _LPAR expr _RPAR | _LSQB expr _RSQB
!string_kw: STRING | WSTRING
// one array element's FB_init arguments (TwinCAT: ARRAY[1..2] OF FB_T[(a := 1), (a := 2)])
fb_init_args: _LPAR [args] _RPAR
// a generic FB's constants (CODESYS, TwinCAT): FB_Buf<100>, FB_Buf<(N * 2)>, FB_T<(n := 5)>
?generic_arg: INTEGER -> generic_int
            | qual_name -> generic_name
            | _LPAR expr _RPAR
            | _LPAR NAME _ASSIGN expr _RPAR -> named_generic_arg
array_dim: expr _DOTDOT expr
         | STAR -> star_dim
enum_value: NAME [_ASSIGN expr]

?initializer: expr
            | _LSQB array_item (_COMMA array_item)* _RSQB -> array_init
            | _LPAR field_init (_COMMA field_init)* _COMMA? _RPAR -> struct_init
            | _LPAR _RPAR -> struct_init
?array_item: initializer -> single_item
           | INTEGER _LPAR [initializer] _RPAR -> repeated_item
field_init: NAME _ASSIGN initializer

var_blocks: var_block*
var_block: var_kind var_qualifier* (var_decl | _SEMI)* _END_VAR
!var_kind: VAR | VAR_INPUT | VAR_OUTPUT | VAR_IN_OUT | VAR_TEMP | VAR_GLOBAL | VAR_EXTERNAL
         | VAR_STAT | VAR_INST | VAR_CONFIG | VAR_ACCESS | VAR_GENERIC
!var_qualifier: CONSTANT | RETAIN | NON_RETAIN | PERSISTENT
var_decl: name_list [_AT ADDRESS] _COLON type_spec [NAME] [_ASSIGN initializer] _SEMI
        | config_path _AT ADDRESS _COLON type_spec [_ASSIGN initializer] _SEMI -> config_decl
        | _AT ADDRESS _COLON type_spec [_ASSIGN initializer] _SEMI -> anonymous_at_decl
        | name_list _COLON access_path _COLON type_spec [NAME] _SEMI -> access_decl
?access_path: qual_name | ADDRESS
config_path: NAME (_DOT NAME)+
"""

ST_TOP = r"""
start: _top_item*
_top_item: program_pou | fb_pou | class_pou | function_pou | type_block | interface | configuration
         | global_block | method | property | action

// a ';' after a header is accepted, as CODESYS and TwinCAT do
program_pou: PROGRAM modifiers NAME _SEMI? var_blocks body_items _END_PROGRAM
fb_pou: FUNCTION_BLOCK modifiers NAME [_EXTENDS extends_ref] [_IMPLEMENTS qual_list] _SEMI? var_blocks body_items _END_FUNCTION_BLOCK
      // TwinCAT writes a generic block's VAR_GENERIC CONSTANT before EXTENDS/IMPLEMENTS
      | FUNCTION_BLOCK modifiers NAME generic_head _EXTENDS extends_ref [_IMPLEMENTS qual_list] _SEMI? var_blocks body_items _END_FUNCTION_BLOCK -> fb_pou_generic_head
      | FUNCTION_BLOCK modifiers NAME generic_head _IMPLEMENTS qual_list _SEMI? var_blocks body_items _END_FUNCTION_BLOCK -> fb_pou_generic_head_impl
generic_head: var_block
// a base block with its generic constants: EXTENDS FB_Base<7>
extends_ref: qual_name
           | qual_name LT generic_arg (_COMMA generic_arg)* GT -> generic_extends
// IEC 61131-3 ed.3 CLASS: a function block whose behaviour is all in its methods
class_pou: CLASS modifiers NAME [_EXTENDS qual_name] [_IMPLEMENTS qual_list] _SEMI? var_blocks body_items _END_CLASS
function_pou: FUNCTION modifiers NAME [_COLON type_spec] _SEMI? var_blocks body_items _END_FUNCTION
qual_list: qual_name (_COMMA qual_name)* _COMMA?
modifiers: modifier*
!modifier: PUBLIC | PRIVATE | PROTECTED | INTERNAL | ABSTRACT | FINAL

// statements, SFC elements and members in one flat list; the transformer sorts them
body_items: _body_item*
_body_item: stmt | step | transition | action | method | property

method: METHOD modifiers NAME [_COLON type_spec] _SEMI? var_blocks stmt_list _END_METHOD
property: PROPERTY modifiers NAME _COLON type_spec _SEMI? accessor* _END_PROPERTY
// TwinCAT writes an accessor's access specifier in its declaration, after GET/SET
accessor: modifiers NAME modifiers var_blocks stmt_list accessor_end
!accessor_end: END_GET | END_SET
action: ACTION NAME _COLON? stmt_list _END_ACTION

interface: INTERFACE modifiers NAME [_EXTENDS qual_list] _SEMI? _iface_item* _END_INTERFACE
_iface_item: method | property

type_block: TYPE type_decl* _END_TYPE
type_decl: NAME [_EXTENDS qual_name] _COLON type_spec [_ASSIGN initializer] _SEMI?

global_block: var_block

// SFC in its IEC textual form
step: INITIAL_STEP NAME _COLON action_assoc* _END_STEP
    | STEP NAME _COLON action_assoc* _END_STEP
action_assoc: NAME _LPAR [action_args] _RPAR _SEMI
action_args: NAME (_COMMA expr)*
transition: TRANSITION [NAME] [transition_priority] _FROM step_set _TO step_set _ASSIGN expr _SEMI _END_TRANSITION
transition_priority: _LPAR NAME _ASSIGN INTEGER _RPAR
step_set: NAME
        | _LPAR NAME (_COMMA NAME)+ _RPAR

// configurations
configuration: CONFIGURATION NAME var_blocks _config_item* _END_CONFIGURATION
_config_item: resource | task | program_config
resource: RESOURCE NAME NAME qual_name var_blocks _resource_item* _END_RESOURCE
_resource_item: task | program_config
task: TASK NAME _LPAR [task_params] _RPAR _SEMI
task_params: task_param (_COMMA task_param)*
task_param: NAME _ASSIGN expr
program_config: PROGRAM [program_retain] NAME [NAME NAME] _COLON qual_name [_LPAR [args] _RPAR] _SEMI
!program_retain: RETAIN | NON_RETAIN
"""

ST_GRAMMAR = TERMINALS + COMMON + ST_TOP

# the .seq sequence-chart format (:mod:`.seq`): the same expressions, statements and
# declarations
SEQ_TOP = r"""
%declare SEQUENCE INPUT OUTPUT INITIAL WHEN AFTER _GOTO JOIN

start: [header] _seq_item*
header: SEQUENCE NAME
_seq_item: seq_decl | seq_step | seq_join | seq_action

seq_decl: (INPUT | OUTPUT | VAR) seq_var (_COMMA seq_var)*
seq_var: NAME [_COLON type_spec] [_ASSIGN initializer]

seq_step: [INITIAL] STEP NAME _COLON? _step_item*
_step_item: seq_assoc | seq_when
seq_assoc: NAME [TIME_LIT] NAME
seq_when: WHEN expr _goto seq_targets
        | AFTER TIME_LIT [WHEN expr] _goto seq_targets -> seq_after
_goto: _ARROW | _GOTO
seq_targets: NAME
           | _LPAR NAME (_COMMA NAME)* _RPAR
seq_join: JOIN NAME (_COMMA NAME)+ [WHEN expr] _goto seq_targets
seq_action: ACTION NAME _COLON? stmt_list _END_ACTION
"""

SEQ_GRAMMAR = TERMINALS + COMMON + SEQ_TOP

# every grammar by name, as :mod:`.tables` keeps their LALR tables
GRAMMARS = {"st": ST_GRAMMAR, "seq": SEQ_GRAMMAR}
